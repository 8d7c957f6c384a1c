#!/usr/bin/env python3
"""The layer order of the whole tree (docs/architecture.md "Layers") and of
the files of src/model (docs/model.md "Layers").

    check_layers.py [--nm NM] --module NAME=LIB ... [--src NAME=DIR ...]
                                                   check built code
    check_layers.py --selftest --cc CC [--nm NM]   show that the check fails on
                                                   crafted violations

Runs `nm` on every module's static library (or object files), maps every
symbol an object defines to its module and source file, and every undefined
reference to the module and file that define it. Fails when

  - a library belongs to no module of MODULE_LAYERS (a new module must be
    given a layer below),
  - a module references a symbol defined by a module of its own layer or of a
    higher one (each module calls only modules of lower layers),
  - the graph of source files of the whole tree (an edge per referenced file)
    has a cycle, within a module or across modules,
  - a file of src/model is in no layer of MODEL_LAYERS or calls a file of a
    higher model layer.

It also reads the #include "<dir>/<header>" lines of the sources (--src): a
file may include another module's header under src/ only when that header is
one of the module's INTERFACE headers and the module is in a lower layer;
within src/model, a file includes only model headers of its own layer or
below. Public headers (include/sooc3d/) are not checked here.
"""
import argparse
import os
import re
import subprocess
import sys
import tempfile

# The modules in layer order, lowest first. A module calls only modules of
# lower layers; modules of one layer do not call each other. `drivers` is
# the folder drivers/; cvshim, slamshim and lcshim are the C++ shims of cv, slam and drivers;
# cli (the sooc3d command, a program) is checked for its includes only.
MODULE_LAYERS = [
    ("base", ["core"]),
    ("math", ["math"]),
    ("engines and stores", ["nn", "data", "cluster", "cogmap", "render", "table"]),
    ("readers and sources", ["gen", "logs", "view", "cv"]),
    ("tracking", ["slam"]),
    ("frame path", ["frames"]),
    ("network", ["model"]),
    ("meshes", ["mesh"]),
    ("mappers", ["mapper", "global"]),
    ("finetuning", ["finetune"]),
    ("evaluation", ["eval"]),
    ("training and sensors", ["train", "drivers"]),
    ("node", ["node"]),
    ("command", ["cli"]),
]
MODULE_ALIAS = {"cvshim": "cv", "lcshim": "drivers", "slamshim": "slam"}
MODULE_LAYER = {m: i for i, (_, mods) in enumerate(MODULE_LAYERS) for m in mods}

# Headers under src/<module>/ that the modules above it may include: the
# module's internal interface (not installed). Every other header under
# src/<module>/ is private to that module.
INTERFACE = {
    "model": {"weights.h", "decoder.h", "refine.h", "step.h", "propose.h", "dec_own.h"},
    "data": {"yaml_doc.h"},
    "nn": {"nn.h", "nn_kern.h", "nn_refine.h"},
    "cv": {"cvmat.hpp"},
}

# Layer of every source file of src/model (by base name, without .c) and of
# its headers.
LAYERS = [
    ("weights", ["model", "kern"], ["weights.h"]),
    ("decoder", ["decoder", "dec_rays", "dec_kl", "dec_own", "field"], ["decoder.h", "dec_own.h"]),
    ("refine", ["refine"], ["refine.h"]),
    ("step", ["step", "workspace", "propose"], ["step.h", "propose.h"]),
]
FILE_LAYER = {f: i for i, (_, files, _) in enumerate(LAYERS) for f in files}
HEADER_LAYER = {h: i for i, (_, _, hdrs) in enumerate(LAYERS) for h in hdrs}


def layer_name(i):
    return "%d (%s)" % (i, LAYERS[i][0])


def module_layer_name(m):
    i = MODULE_LAYER[m]
    return "%d (%s)" % (i, MODULE_LAYERS[i][0])


def run_nm(nm, module, paths, files):
    """Add {(module, file): (defined set, undefined set)} from nm on archives / objects."""
    out = subprocess.run([nm, "-A"] + paths, capture_output=True, text=True)
    if out.returncode != 0:
        raise SystemExit("nm failed: %s" % out.stderr.strip())
    for line in out.stdout.splitlines():
        # "lib.a:member.c.o:0000 T name", "obj.o:0000 T name", "obj.o:         U name"
        m = re.match(r"^(.*?):\s*(?:[0-9a-fA-F]+\s+)?([A-Za-z?-])\s+(\S+)$", line)
        if not m:
            continue
        where, kind, sym = m.groups()
        member = where.split(":")[-1]
        base = os.path.basename(member)
        base = re.sub(r"(\.c|\.cpp)?\.o(bj)?$", "", base)
        d, u = files.setdefault((module, base), (set(), set()))
        if kind == "U":
            u.add(sym)
        elif kind.isupper():
            d.add(sym)
    return files


def find_cycles(edges):
    """Every cycle of a {node: {node: ...}} graph found by depth-first search, once per node set."""
    state, stack, seen, cycles = {}, [], set(), []
    sys.setrecursionlimit(max(1000, 4 * len(edges) + 100))

    def dfs(f):
        state[f] = 1
        stack.append(f)
        for g in sorted(edges.get(f, ())):
            if state.get(g) == 1:
                cyc = stack[stack.index(g):] + [g]
                key = frozenset(cyc)
                if key not in seen:
                    seen.add(key)
                    cycles.append(cyc)
            elif g not in state:
                dfs(g)
        stack.pop()
        state[f] = 2

    for f in sorted(edges):
        if f not in state:
            dfs(f)
    return cycles


def fname(key):
    return "%s/%s" % key


def check_graph(files):
    """Errors of a {(module, file): (defined, undefined)} map (an empty list: all good)."""
    errors = []
    owner = {}
    for f, (d, _) in sorted(files.items()):
        for s in d:
            owner.setdefault(s, f)
    for m in sorted({m for m, _ in files}):
        if m not in MODULE_LAYER:
            errors.append("module %s: in no layer (add it to MODULE_LAYERS in %s)" %
                          (m, os.path.basename(__file__)))
    for m, f in sorted(files):
        if m == "model" and f not in FILE_LAYER:
            errors.append("model/%s: in no model layer (add it to LAYERS in %s)" % (f, os.path.basename(__file__)))
    edges = {f: {} for f in files}
    for f, (_, u) in files.items():
        for s in u:
            g = owner.get(s)
            if g is None or g == f:
                continue
            edges[f].setdefault(g, []).append(s)
    for f in sorted(edges):
        for g in sorted(edges[f]):
            syms = ", ".join(sorted(edges[f][g])[:6]) + (", ..." if len(edges[f][g]) > 6 else "")
            mf, mg = f[0], g[0]
            if mf != mg:
                lf, lg = MODULE_LAYER.get(mf), MODULE_LAYER.get(mg)
                if lf is not None and lg is not None and lg >= lf:
                    errors.append("%s (module layer %s) calls %s (module layer %s): %s" %
                                  (fname(f), module_layer_name(mf), fname(g), module_layer_name(mg), syms))
            elif mf == "model":
                lf, lg = FILE_LAYER.get(f[1]), FILE_LAYER.get(g[1])
                if lf is not None and lg is not None and lg > lf:
                    errors.append("%s (layer %s) calls %s (layer %s): %s" %
                                  (fname(f), layer_name(lf), fname(g), layer_name(lg), syms))
    for cyc in find_cycles(edges):
        errors.append("cycle: " + " -> ".join(fname(k) for k in cyc))
    return errors, edges


INCLUDE_RE = re.compile(r'\s*#\s*include\s+"([A-Za-z0-9_]+)/([^"]+)"')


def check_includes(src_dirs):
    """src_dirs: [(module, folder)]. Errors of the #include lines of the folders' sources."""
    errors = []
    known = set(MODULE_LAYER) | {m for m, _ in src_dirs}
    for mod, d in src_dirs:
        for name in sorted(os.listdir(d)):
            if not name.endswith((".c", ".h", ".cpp")):
                continue
            layer = None
            if mod == "model":
                layer = FILE_LAYER.get(name[:-2]) if name.endswith(".c") else HEADER_LAYER.get(name)
            with open(os.path.join(d, name), encoding="utf-8") as fh:
                for n, line in enumerate(fh, 1):
                    m = INCLUDE_RE.match(line)
                    if not m:
                        continue
                    other, h = m.groups()
                    if other == "sooc3d" or other not in known:
                        continue
                    where = "%s/%s:%d" % (mod, name, n)
                    if other != mod:
                        lo, lm = MODULE_LAYER.get(other), MODULE_LAYER.get(mod)
                        if h not in INTERFACE.get(other, ()):
                            errors.append("%s includes %s/%s, a private header of module %s" % (where, other, h, other))
                        elif lo is None or lm is None or lo >= lm:
                            errors.append("%s includes %s/%s of module %s, not in a lower layer" %
                                          (where, other, h, other))
                    elif mod == "model" and layer is not None:
                        hl = HEADER_LAYER.get(h)
                        if hl is None:
                            errors.append("%s includes model/%s, a header in no layer" % (where, h))
                        elif hl > layer:
                            errors.append("%s (layer %s) includes model/%s (layer %s)" %
                                          (where, layer_name(layer), h, layer_name(hl)))
    return errors


def check(nm, modules, src_dirs, verbose=True):
    files = {}
    for mod, paths in modules:
        run_nm(nm, MODULE_ALIAS.get(mod, mod), paths, files)
    errors, edges = check_graph(files)
    errors += check_includes(src_dirs)
    if verbose:
        mods = {}
        for (mf, _), out in edges.items():
            for (mg, _) in out:
                if mg != mf:
                    mods.setdefault(mf, set()).add(mg)
        for m in sorted({m for m, _ in files}, key=lambda m: (MODULE_LAYER.get(m, 99), m)):
            print("%-9s layer %-26s -> %s" % (m, module_layer_name(m) if m in MODULE_LAYER else "?",
                                              ", ".join(sorted(mods.get(m, ()))) or "-"))
        nfiles = len(files)
        nedges = sum(len(v) for v in edges.values())
        print("%d source files, %d file-to-file call edges" % (nfiles, nedges))
    return errors


# ------------------------------------------------------------------ self-test

# Synthetic symbol tables: {(module, file): (defined, undefined)}.
SYNTHETIC = [
    ("clean tree", {
        ("core", "status"): ({"sooc_seterr"}, set()),
        ("math", "geom"): ({"sooc_se3_mul"}, {"sooc_seterr"}),
        ("model", "model"): ({"sooc_model_create"}, {"sooc_se3_mul", "sooc_seterr"}),
        ("mapper", "mapper"): ({"sooc_mapper_update"}, {"sooc_model_create"}),
    }, None),
    ("a lower module calls a higher one", {
        ("math", "geom"): ({"sooc_se3_mul"}, {"sooc_model_create"}),
        ("model", "model"): ({"sooc_model_create"}, {"sooc_se3_mul"}),
    }, "math/geom (module layer 1 (math)) calls model/model (module layer 6 (network))"),
    ("two modules of one layer call each other", {
        ("data", "seq"): ({"sooc_seq_open"}, {"sooc_cluster_add"}),
        ("cluster", "cluster"): ({"sooc_cluster_add"}, set()),
    }, "data/seq (module layer 2 (engines and stores)) calls cluster/cluster"),
    ("a call circle between two files of one module", {
        ("drivers", "sensor"): ({"sooc_sensor_open", "sooc__timebase"}, {"sooc__replay_vt"}),
        ("drivers", "replay"): ({"sooc__replay_vt"}, {"sooc__timebase"}),
    }, "cycle: drivers/replay -> drivers/sensor -> drivers/replay"),
    ("a call circle through three files", {
        ("gen", "gen"): ({"a"}, {"b"}),
        ("gen", "tabletop"): ({"b"}, {"c"}),
        ("gen", "noise"): ({"c"}, {"a"}),
    }, "cycle: gen/gen -> gen/tabletop -> gen/noise -> gen/gen"),
    ("a module in no layer", {
        ("core", "status"): ({"sooc_seterr"}, set()),
        ("newmod", "track"): ({"sooc_newmod_track"}, {"sooc_seterr"}),
    }, "module newmod: in no layer"),
    ("a model file in no model layer", {
        ("model", "model"): ({"mdl_w"}, set()),
        ("model", "newfile"): ({"mdl_n"}, {"mdl_w"}),
    }, "model/newfile: in no model layer"),
]

# Crafted sources compiled with the C compiler: (what, {module/file: source}, expected error or None).
COMPILED = [
    ("clean model layers", {
        "model/model.c": "int mdl_w(void) { return 1; }\n",
        "model/decoder.c": "int mdl_w(void);\nint mdl_d(void) { return mdl_w(); }\n",
        "model/step.c": "int mdl_d(void);\nint mdl_s(void) { return mdl_d(); }\n",
        "global/global.c": '#include "model/step.h"\nint mdl_s(void);\nint glb(void) { return mdl_s(); }\n',
    }, None),
    ("a lower model layer calls a higher one", {
        "model/model.c": "int sooc_mdl_step_free(void);\nint mdl_w(void) { return sooc_mdl_step_free(); }\n",
        "model/step.c": "int mdl_w(void);\nint sooc_mdl_step_free(void) { return 0; }\nint mdl_s(void) { return mdl_w(); }\n",
    }, "model/model (layer 0 (weights)) calls model/step (layer 3 (step))"),
    ("an upward include within src/model", {
        "model/decoder.c": '#include "model/step.h"\nint mdl_d(void) { return 0; }\n',
    }, "model/decoder.c:1 (layer 1 (decoder)) includes model/step.h (layer 3 (step))"),
    ("another module's private header", {
        "global/global.c": '#include "cogmap/mapstore_impl.h"\nint glb(void) { return 0; }\n',
    }, "global/global.c:1 includes cogmap/mapstore_impl.h, a private header of module cogmap"),
    ("an interface header of a higher module", {
        "cluster/cluster.c": '#include "model/propose.h"\nint clu(void) { return 0; }\n',
    }, "cluster/cluster.c:1 includes model/propose.h of module model, not in a lower layer"),
]


def selftest(cc, nm):
    ok = True

    def report(what, errs, expect):
        good = not errs if expect is None else any(expect in e for e in errs)
        print("selftest %-46s %s%s" % (what + ":", "ok" if good else "WRONG",
                                       "" if not errs else " (" + "; ".join(errs) + ")"))
        return good

    for what, table, expect in SYNTHETIC:
        errs, _ = check_graph(table)
        ok = report(what, errs, expect) and ok
    for what, srcs, expect in COMPILED:
        with tempfile.TemporaryDirectory() as d:
            for mod, hdr in (("model", "step.h"), ("model", "propose.h"), ("cogmap", "mapstore_impl.h")):
                os.makedirs(os.path.join(d, mod), exist_ok=True)
                with open(os.path.join(d, mod, hdr), "w") as fh:
                    fh.write("/* crafted */\n")
            modules, dirs = {}, set()
            for rel, text in srcs.items():
                mod = rel.split("/")[0]
                sd = os.path.join(d, "src_" + mod)
                os.makedirs(sd, exist_ok=True)
                p = os.path.join(sd, os.path.basename(rel))
                with open(p, "w") as fh:
                    fh.write(text)
                o = p[:-2] + ".c.o"
                r = subprocess.run([cc, "-c", "-I", d, p, "-o", o], capture_output=True, text=True)
                if r.returncode != 0:
                    print("selftest %s: cannot compile %s: %s" % (what, rel, r.stderr.strip()))
                    return False
                modules.setdefault(mod, []).append(o)
                dirs.add((mod, sd))
            errs = check(nm, sorted(modules.items()), sorted(dirs), verbose=False)
            ok = report(what, errs, expect) and ok
    return ok


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--nm", default="nm")
    ap.add_argument("--cc", default="cc")
    ap.add_argument("--module", action="append", default=[], metavar="NAME=LIB",
                    help="a module's static library (or object file); repeat per module")
    ap.add_argument("--src", action="append", default=[], metavar="NAME=DIR",
                    help="a module's source folder whose includes to check")
    ap.add_argument("--selftest", action="store_true")
    a = ap.parse_args()
    if a.selftest:
        ok = selftest(a.cc, a.nm)
        print("check_layers selftest: %s" % ("every crafted violation caught" if ok else "FAILED"))
        return 0 if ok else 1
    if not a.module:
        ap.error("no --module NAME=LIB")
    modules = {}
    for spec in a.module:
        name, _, path = spec.partition("=")
        modules.setdefault(name, []).append(path)
    src = [tuple(s.split("=", 1)) for s in a.src]
    errors = check(a.nm, sorted(modules.items()), src)
    for e in errors:
        print("LAYERS: " + e)
    print("check_layers: %d problem(s)" % len(errors))
    return 1 if errors else 0


if __name__ == "__main__":
    sys.exit(main())

#!/usr/bin/env python3
"""The layer order of src/model and src/global (docs/model.md "Layers").

    check_layers.py [--nm NM] LIB_OR_OBJECT...     check built code
    check_layers.py --selftest --cc CC [--nm NM]   show that the check fails on
                                                   crafted violations

Runs `nm` on the object files of the model and global modules (their static
libraries, or .o files), maps every symbol an object defines to its source
file, and every undefined reference to the file that defines it. Fails when

  - a file is in no layer (a new file must be given one below),
  - a file references a symbol defined in a higher layer, or
  - the graph of files (an edge per referenced file) has a cycle, even
    within one layer.

It also reads the #include "model/..." lines of the sources (with --src):
an internal header belongs to a layer, and a file may include only headers
of its own layer or below.
"""
import argparse
import os
import re
import subprocess
import sys
import tempfile

# Layer of every source file (by base name, without .c) and internal header.
LAYERS = [
    ("weights", ["model", "kern"], ["weights.h"]),
    ("decoder", ["decoder", "dec_own", "field"], ["decoder.h", "dec_own.h"]),
    ("refine", ["refine"], ["refine.h"]),
    ("step", ["step", "workspace", "propose"], ["step.h", "propose.h"]),
    ("mapper", ["mapper", "mapper_gate", "mapper_geo", "objgeom"], ["mapper_geo.h"]),
    ("global", ["global"], []),
]
FILE_LAYER = {f: i for i, (_, files, _) in enumerate(LAYERS) for f in files}
HEADER_LAYER = {h: i for i, (_, _, hdrs) in enumerate(LAYERS) for h in hdrs}


def layer_name(i):
    return "%d (%s)" % (i, LAYERS[i][0])


def run_nm(nm, paths):
    """{file: (defined set, undefined set)} from nm on archives / objects."""
    out = subprocess.run([nm, "-A"] + paths, capture_output=True, text=True)
    if out.returncode != 0:
        raise SystemExit("nm failed: %s" % out.stderr.strip())
    files = {}
    for line in out.stdout.splitlines():
        # "lib.a:member.c.o:0000 T name", "obj.o:0000 T name", "obj.o:         U name"
        m = re.match(r"^(.*?):\s*(?:[0-9a-fA-F]+\s+)?([A-Za-z?-])\s+(\S+)$", line)
        if not m:
            continue
        where, kind, sym = m.groups()
        member = where.split(":")[-1]
        base = os.path.basename(member)
        base = re.sub(r"(\.c)?\.o(bj)?$", "", base)
        d, u = files.setdefault(base, (set(), set()))
        if kind == "U":
            u.add(sym)
        elif kind.isupper():
            d.add(sym)
    return files


def check_graph(files):
    """Errors of a {file: (defined, undefined)} map (an empty list: all good)."""
    errors = []
    owner = {}
    for f, (d, _) in files.items():
        for s in d:
            owner.setdefault(s, f)
    for f in sorted(files):
        if f not in FILE_LAYER:
            errors.append("%s: in no layer (add it to LAYERS in %s)" % (f, os.path.basename(__file__)))
    edges = {f: {} for f in files}
    for f, (_, u) in files.items():
        for s in u:
            g = owner.get(s)
            if g is None or g == f:
                continue
            edges[f].setdefault(g, []).append(s)
    for f in sorted(edges):
        for g in sorted(edges[f]):
            lf, lg = FILE_LAYER.get(f), FILE_LAYER.get(g)
            if lf is not None and lg is not None and lg > lf:
                errors.append("%s (layer %s) calls %s (layer %s): %s" %
                              (f, layer_name(lf), g, layer_name(lg), ", ".join(sorted(edges[f][g]))))
    # cycles (depth-first search; report each cycle once, by its file list)
    state, stack, seen = {}, [], set()

    def dfs(f):
        state[f] = 1
        stack.append(f)
        for g in sorted(edges[f]):
            if state.get(g) == 1:
                cyc = stack[stack.index(g):] + [g]
                key = frozenset(cyc)
                if key not in seen:
                    seen.add(key)
                    errors.append("cycle: " + " -> ".join(cyc))
            elif g not in state:
                dfs(g)
        stack.pop()
        state[f] = 2

    for f in sorted(edges):
        if f not in state:
            dfs(f)
    return errors, edges


def check_includes(src_dirs):
    errors = []
    for d in src_dirs:
        for name in sorted(os.listdir(d)):
            if not name.endswith((".c", ".h")):
                continue
            if name.endswith(".c"):
                layer = FILE_LAYER.get(name[:-2])
            else:
                layer = HEADER_LAYER.get(name)
            if layer is None:
                if name.endswith(".c"):
                    errors.append("%s: in no layer" % name)
                continue
            with open(os.path.join(d, name), encoding="utf-8") as fh:
                for n, line in enumerate(fh, 1):
                    m = re.match(r'\s*#\s*include\s+"model/([^"]+)"', line)
                    if not m:
                        continue
                    h = m.group(1)
                    hl = HEADER_LAYER.get(h)
                    if hl is None:
                        errors.append("%s:%d: includes model/%s, a header in no layer" % (name, n, h))
                    elif hl > layer:
                        errors.append("%s:%d (layer %s) includes model/%s (layer %s)" %
                                      (name, n, layer_name(layer), h, layer_name(hl)))
    return errors


def check(nm, paths, src_dirs, verbose=True):
    files = run_nm(nm, paths)
    errors, edges = check_graph(files)
    if src_dirs:
        errors += check_includes(src_dirs)
    if verbose:
        for f in sorted(files, key=lambda f: (FILE_LAYER.get(f, 99), f)):
            calls = ", ".join("%s (%d)" % (g, len(edges[f][g])) for g in sorted(edges[f]))
            lf = FILE_LAYER.get(f)
            print("%-12s layer %-12s -> %s" % (f, layer_name(lf) if lf is not None else "?", calls or "-"))
    return errors


SELFTEST = [
    # (what, {file: source}, expected error substring or None)
    ("clean layers", {
        "model.c": "int mdl_w(void) { return 1; }\n",
        "decoder.c": "int mdl_w(void);\nint mdl_d(void) { return mdl_w(); }\n",
        "step.c": "int mdl_d(void);\nint mdl_s(void) { return mdl_d(); }\n",
    }, None),
    ("a lower layer calls a higher one", {
        "model.c": "int mdl_step_free(void);\nint mdl_w(void) { return mdl_step_free(); }\n",
        "step.c": "int mdl_w(void);\nint mdl_step_free(void) { return 0; }\nint mdl_s(void) { return mdl_w(); }\n",
    }, "model (layer 0 (weights)) calls step (layer 3 (step))"),
    ("a cycle within one layer", {
        "mapper.c": "int mdl_g(void);\nint mdl_m(void) { return mdl_g(); }\n",
        "mapper_gate.c": "int mdl_m(void);\nint mdl_g(void) { return mdl_m(); }\n",
    }, "cycle: "),
    ("a file in no layer", {
        "model.c": "int mdl_w(void) { return 1; }\n",
        "newfile.c": "int mdl_w(void);\nint mdl_n(void) { return mdl_w(); }\n",
    }, "newfile: in no layer"),
    ("an upward include", {
        "decoder.c": '#include "model/step.h"\nint mdl_d(void) { return 0; }\n',
    }, "decoder.c:1 (layer 1 (decoder)) includes model/step.h (layer 3 (step))"),
]


def selftest(cc, nm):
    ok = True
    for what, srcs, expect in SELFTEST:
        with tempfile.TemporaryDirectory() as d:
            os.makedirs(os.path.join(d, "model"))
            with open(os.path.join(d, "model", "step.h"), "w") as fh:
                fh.write("/* crafted */\n")
            objs = []
            for name, text in srcs.items():
                p = os.path.join(d, name)
                with open(p, "w") as fh:
                    fh.write(text)
                o = p[:-2] + ".c.o"
                r = subprocess.run([cc, "-c", "-I", d, p, "-o", o], capture_output=True, text=True)
                if r.returncode != 0:
                    print("selftest %s: cannot compile %s: %s" % (what, name, r.stderr.strip()))
                    return False
                objs.append(o)
            errs = check(nm, objs, [d], verbose=False)
            if expect is None:
                good = not errs
            else:
                good = any(expect in e for e in errs)
            print("selftest %-36s %s%s" % (what + ":", "ok" if good else "WRONG",
                                           "" if not errs else " (" + "; ".join(errs) + ")"))
            ok = ok and good
    return ok


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--nm", default="nm")
    ap.add_argument("--cc", default="cc")
    ap.add_argument("--src", action="append", default=[], help="source folder whose includes to check")
    ap.add_argument("--selftest", action="store_true")
    ap.add_argument("paths", nargs="*")
    a = ap.parse_args()
    if a.selftest:
        ok = selftest(a.cc, a.nm)
        print("check_layers selftest: %s" % ("every crafted violation caught" if ok else "FAILED"))
        return 0 if ok else 1
    if not a.paths:
        ap.error("no libraries or objects")
    errors = check(a.nm, a.paths, a.src)
    for e in errors:
        print("LAYERS: " + e)
    print("check_layers: %d problem(s)" % len(errors))
    return 1 if errors else 0


if __name__ == "__main__":
    sys.exit(main())

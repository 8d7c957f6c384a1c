#!/usr/bin/env bash
# Regenerate the tables of docs/results.md from measured JSON.
#
#   bash scripts/results.sh [DIR]                rewrite every table whose JSON files are all in DIR
#                                                (default out/results); the others stay as they are
#   bash scripts/results.sh --print NAME [DIR]   print one table to stdout
#   bash scripts/results.sh --list               the tables and the JSON files each one reads
#   bash scripts/results.sh --check              every table of docs/results.md is known here
#
# The JSON files are what `sooc3d eval --json F` writes (synthetic datasets or a
# recorded sequence) and the last line a benchmark prints (`bench_x > F` is enough:
# the last line of F that parses as JSON is read). docs/results.md names, above each
# table, the commands that write its files. A table sits between the lines
# `<!-- results.sh: NAME -->` and `<!-- end results.sh -->`.
set -euo pipefail
cd "$(dirname "$0")/.."
exec python3 - "$@" <<'PY'
import json, math, os, re, sys

DOC = "docs/results.md"

# ---- table definitions -------------------------------------------------------------------
# matrix:      rows model x view, columns metric x scale (the paper's Table 1 layout)
# composition: mIoU at m and composition-matched at l / xl, and the drop against m
# rows:        one row per (label, files, model, scale); columns (view, key)
# real:        one row per (label, file, model) of `sooc3d eval` on a recorded sequence
# bench:       one row per (label, file, key, format) of benchmark JSON
UNITY_METRICS = [("miou", "mIoU ↑"), ("rgb_rmse", "RGB RMSE ↓"), ("depth_rmse", "depth RMSE ↓"),
                 ("l2", "L2 (m) ↓")]
SC4 = ["s", "m", "l", "xl"]
FT_COLS = [("Q", "miou", "s", "query mIoU s"), ("Q", "miou", "m", "m"), ("Q", "miou", "l", "l"),
           ("Q", "miou", "xl", "xl"),
           ("Q", "mesh_acc_cm", "m/l/xl", "mesh acc (cm) m / l / xl"),
           ("Q", "mesh_comp_cm", "m/l/xl", "mesh comp (cm) m / l / xl"),
           ("Q", "extent_err_cm", "m", "box error (cm) m")]


def ft_files(prefix, scales):
    return ["%s_%s.json" % (prefix, s) for s in scales]


TABLES = {
    "unity": dict(kind="matrix", files=["unity.json"],
                  models=[("SOOC3D", "SOOC3D"), ("global-frame", "global-frame")],
                  metrics=UNITY_METRICS, scales=SC4),
    "unity_composition": dict(kind="composition", files=["unity.json"],
                              models=[("SOOC3D", "SOOC3D"), ("global-frame", "global-frame")]),
    "unity_recall": dict(kind="rows", files=["unity.json"],
                         head=["model", "view", "scale"],
                         rows=[(["SOOC3D", "Q", "m"], "SOOC3D", "m"), (["SOOC3D", "Q", "l"], "SOOC3D", "l"),
                               (["SOOC3D", "Q", "xl"], "SOOC3D", "xl"),
                               (["global-frame", "Q", "m"], "global-frame", "m"),
                               (["global-frame", "Q", "l"], "global-frame", "l")],
                         cols=[("Q", "n_views", "views"), ("Q", "miou_hungarian", "mIoU Hungarian"),
                               ("Q", "matched_frac", "matched"), ("Q", "recall_lt3m", "recall <3 m"),
                               ("Q", "recall_3to5m", "recall 3-5 m"), ("Q", "recall_gt5m", "recall >5 m"),
                               ("Q", "rgb_rmse_obj", "RGB RMSE objects")]),
    "finetune": dict(kind="ftrows",
                     rows=[("SOOC3D (unity)", ft_files("ft_unity", ["m", "l", "xl"]), "SOOC3D"),
                           ("SOOC3D+ft (unity)", ft_files("ft_unity", ["m", "l", "xl"]), "SOOC3D+ft"),
                           ("SOOC3D+ft (unity), no births and deaths (`--ft-no-birth`)",
                            ft_files("ft_unity_nobirth", ["m", "l", "xl"]), "SOOC3D+ft"),
                           ("SOOC3D (blender)", ft_files("ft_blender", SC4), "SOOC3D"),
                           ("SOOC3D+ft (blender, 600 steps)", ft_files("ft_blender", SC4), "SOOC3D+ft"),
                           ("SOOC3D+ft (blender, 300 steps, no births)",
                            ft_files("ft_blender300_nobirth", SC4), "SOOC3D+ft")],
                     cols=FT_COLS),
    "blender": dict(kind="matrix", files=ft_files("ft_blender", SC4),
                    models=[("SOOC3D (blender)", "SOOC3D"), ("SOOC3D+ft (blender)", "SOOC3D+ft")],
                    metrics=UNITY_METRICS[:3], scales=SC4),
    "tabletop": dict(kind="rows", files=["tabletop.json", "tabletop_ft.json", "tabletop_ft_nobirth.json"],
                     head=["model", "scale"],
                     rows=[(["shipped", "m"], "tabletop", "m", "tabletop.json"),
                           (["", "l"], "tabletop", "l", "tabletop.json"),
                           (["", "l, composition-matched to m"], "tabletop", "l", "tabletop.json", "cm"),
                           (["shipped, SOOC3D+ (births, finetuning, deaths)", "m"], "tabletop+ft", "m",
                            "tabletop_ft.json"),
                           (["", "l"], "tabletop+ft", "l", "tabletop_ft.json"),
                           (["", "l, composition-matched to m"], "tabletop+ft", "l", "tabletop_ft.json", "cm"),
                           (["shipped, SOOC3D+ without births (`--ft-no-birth`)", "m"], "tabletop+ft", "m",
                            "tabletop_ft_nobirth.json"),
                           (["", "l, composition-matched to m"], "tabletop+ft", "l",
                            "tabletop_ft_nobirth.json", "cm")],
                     cols=[("Q", "miou", "query mIoU"), ("I", "miou", "input mIoU"),
                           ("Q", "depth_rmse", "query depth RMSE (m)"), ("Q", "l2", "query L2 (m)"),
                           ("Q", "matched_frac", "matched (query)")]),
    "real_rooms": dict(kind="real", labels=False,
                       rows=[("SOOC3D unity", "7scenes.json", "unity"),
                             ("global-frame", "7scenes.json", "global-frame"),
                             ("SOOC3D unity, node's revisit rules", "7scenes_revisit.json", "unity"),
                             ("SOOC3D real", "7scenes_real.json", "real"),
                             ("SOOC3D real, node's revisit rules", "7scenes_real_revisit.json", "real"),
                             ("**SOOC3D+ real**, node's revisit rules (births, 1,500 finetuning steps, deaths)",
                              "7scenes_real_ft.json", "real+ft"),
                             ("SOOC3D+ real, node's revisit rules, no births and deaths",
                              "7scenes_real_ft_nobirth.json", "real+ft")]),
    "real_tabletops": dict(kind="real", labels=True,
                           rows=[("SOOC3D unity, labels set", "lf.json", "unity"),
                                 ("global-frame, labels set", "lf.json", "global-frame"),
                                 ("SOOC3D unity, node's revisit rules, labels set", "lf_revisit.json", "unity"),
                                 ("SOOC3D tabletop, labels set", "lf_tabletop.json", "tabletop"),
                                 ("SOOC3D+ tabletop (births, 300 steps), labels set", "lf_tabletop_ft.json",
                                  "tabletop+ft"),
                                 ("SOOC3D tabletop, masks set", "lf_masks_tabletop.json", "tabletop"),
                                 ("SOOC3D+ tabletop, masks set", "lf_masks_tabletop_ft.json", "tabletop+ft")]),
    "real_tabletop_sets": dict(kind="sets", file="real_tabletop.json",
                               sets=[("YCB-Video 0000", "0000"), ("label-fusion labels", "labels"),
                                     ("label-fusion masks", "masks"),
                                     ("APC shelf bin (agreement with predicted masks)", "scene-0000")],
                               rows=[("geometric", "geometric"), ("online", "sooc3d_tabletop"),
                                     ("online, observed surfaces", "surfaces", "real_tabletop_surfaces.json"),
                                     ("SOOC3D+", "sooc3d_tabletop+ft")]),
    "speed_engine": dict(kind="bench",
                         rows=[("`bench_engine` conv encoder fwd + bwd vs PyTorch", "bench_engine.json",
                                "conv_vs_torch", "{:.2f}×"),
                               ("`bench_engine` decoder MLP vs PyTorch (2 threads)", "bench_engine.json",
                                "mlp_vs_torch", "{:.2f}×"),
                               ("`bench_engine` decoder MLP vs OpenBLAS sgemm peak", "bench_engine.json",
                                "mlp_vs_sgemm_peak", "pct"),
                               ("`bench_engine` decoder MLP GFLOP/s (sgemm peak)", "bench_engine.json",
                                ("mlp_gflops", "sgemm_peak_gflops"), "{:.1f} ({:.1f})"),
                               ("`bench_keyframe` (64×64, K = 7, L = 3) vs PyTorch of the same update", "bench_keyframe.json",
                                "speedup_vs_torch", "{:.2f}×"),
                               ("`bench_keyframe` median update (PyTorch)", "bench_keyframe.json",
                                ("median_ms", "torch_median_ms"), "{:.1f} ms ({:.1f} ms)")]),
    "speed_finetune": dict(kind="bench",
                           rows=[("medium scene, births + finetuning + deaths (s)", "bench_finetune.json",
                                  "m_total_seconds_mean", "{:.1f}"),
                                 ("births / deaths (s)", "bench_finetune.json",
                                  ("m_birth_seconds_mean", "m_death_seconds_mean"), "{:.1f} / {:.1f}"),
                                 ("finetuning (s; per object)", "bench_finetune.json",
                                  ("m_seconds_mean", "m_s_per_object"), "{:.1f} ({:.2f} per object)"),
                                 ("large scene finetuning (s; per object)", "bench_finetune.json",
                                  ("l_seconds", "l_s_per_object"), "{:.1f} ({:.2f} per object)")]),
    "speed_table": dict(kind="bench",
                        rows=[("reader snapshot of 10⁴ objects", "bench_table.json", "snapshot_us", "us_ms"),
                              ("reader per-record read", "bench_table.json", "read_record_ns", "{:.0f} ns"),
                              ("liveness check (flock probe + heartbeat)", "bench_table.json", "alive_check_us",
                               "{:.2f} µs"),
                              ("writer publish, batch of 10⁴ upserts", "bench_table.json", "publish_10k_us",
                               "us_ms"),
                              ("writer publish, one keyframe (10 upserts)", "bench_table.json", "publish_10_us",
                               "{:.1f} µs")]),
}


# ---- reading ---------------------------------------------------------------------------
def load(path):
    """A JSON object: the whole file, or its last line that parses (benchmark output)."""
    text = open(path, encoding="utf-8").read()
    try:
        return json.loads(text)
    except ValueError:
        pass
    for line in reversed(text.splitlines()):
        line = line.strip()
        if line.startswith("{"):
            try:
                return json.loads(line)
            except ValueError:
                continue
    raise SystemExit("results.sh: %s holds no JSON object" % path)


class Cells:
    def __init__(self, d, files):
        self.cells = []
        for f in files:
            for c in load(os.path.join(d, f)).get("cells", []):
                self.cells.append((f, c))

    def get(self, model, scale, view, file=None):
        for f, c in self.cells:
            if c.get("model") == model and c.get("scale") == scale and c.get("view") == view \
                    and (file is None or f == file):
                return c
        return None


def val(cell, key):
    if cell is None or key not in cell:
        return None
    v = cell[key]
    if isinstance(v, dict):
        v = v.get("mean")
    if v is None or (isinstance(v, float) and not math.isfinite(v)):
        return None
    return v


def f3(v, na="-"):
    return na if v is None else "%.3f" % v


def fsig(v):
    if v is None:
        return "-"
    s = "%+.3f" % v
    return "0.000" if s in ("+0.000", "-0.000") else s


# ---- tables ----------------------------------------------------------------------------
def t_matrix(t, d):
    cs = Cells(d, t["files"])
    head = ["model", "view"] + ["%s %s" % (h, s) for _, h in t["metrics"] for s in t["scales"]]
    out = ["| " + " | ".join(head) + " |", "|---|---|" + "---:|" * (len(head) - 2)]
    for label, name in t["models"]:
        for i, view in enumerate(("I", "Q")):
            row = [label if i == 0 else "", view]
            for key, _ in t["metrics"]:
                for s in t["scales"]:
                    v = val(cs.get(name, s, view), key)
                    row.append("n/a" if key == "l2" and view == "I" else f3(v))
            out.append("| " + " | ".join(row) + " |")
    return out


def t_composition(t, d):
    cs = Cells(d, t["files"])
    out = ["| model | view | m | l | xl | drop l / xl |", "|---|---|---:|---:|---:|---:|"]
    for label, name in t["models"]:
        for view in ("I", "Q"):
            m = val(cs.get(name, "m", view), "miou")
            l = val(cs.get(name, "l", view), "miou_composition_matched_m")
            xl = val(cs.get(name, "xl", view), "miou_composition_matched_m")
            drop = lambda x: fsig(None if x is None or m is None else x - m)
            out.append("| %s | %s | %s | %s | %s | %s / %s |" % (label, view, f3(m), f3(l), f3(xl), drop(l), drop(xl)))
    return out


def t_rows(t, d):
    cs = Cells(d, t["files"])
    head = t["head"] + [h for _, _, h in t["cols"]]
    out = ["| " + " | ".join(head) + " |", "|" + "---|" * len(t["head"]) + "---:|" * len(t["cols"])]
    for r in t["rows"]:
        labels, name, scale = r[0], r[1], r[2]
        file = r[3] if len(r) > 3 else None
        cm = len(r) > 4 and r[4] == "cm"
        row = list(labels)
        for view, key, _ in t["cols"]:
            if cm and key != "miou":
                row.append("")
                continue
            v = val(cs.get(name, scale, view, file), "miou_composition_matched_m" if cm else key)
            row.append(("%d" % v if v is not None else "-") if key == "n_views" else f3(v))
        out.append("| " + " | ".join(row) + " |")
    return out


def ft_cell(cs, files, name, view, key, scale):
    for f in files:
        c = cs.get(name, scale, view, f)
        if c is not None:
            return val(c, key)
    return None


def t_ftrows(t, d):
    head = ["model"] + [h for *_, h in t["cols"]]
    out = ["| " + " | ".join(head) + " |", "|---|" + "".join("---|" if "/" in h else "---:|" for *_, h in t["cols"])]
    for label, files, name in t["rows"]:
        cs = Cells(d, files)
        row = [label]
        for view, key, scales, _ in t["cols"]:
            vals = []
            for s in scales.split("/"):
                v = ft_cell(cs, files, name, view, key, s)
                if key.endswith("_cm"):
                    vals.append("-" if v is None else "%.2f" % v if key != "extent_err_cm" else "%.1f" % v)
                else:
                    vals.append("" if v is None else "%.3f" % v)
            row.append(" / ".join(vals))
        out.append("| " + " | ".join(row) + " |")
    return out


def t_real(t, d):
    labels = t["labels"]
    head = ["model", "mapped / query", "depth RMSE (m)", "RGB RMSE"]
    if labels:
        head += ["mIoU", "IoU per labelled object"]
    head += ["entries end / created", "growth, 2nd pass", "never seen (free)"]
    out = ["| " + " | ".join(head) + " |", "|---|" + "---:|" * (len(head) - 1)]
    for label, f, name in t["rows"]:
        c = None
        for cc in load(os.path.join(d, f)).get("cells", []):
            if cc.get("model") == name:
                c = cc
        if c is None:
            raise SystemExit("results.sh: %s has no cell of model '%s'" % (f, name))
        row = [label, "%d / %d" % (c.get("frames_mapped", 0), c.get("frames_query", 0)),
               f3(val(c, "depth_rmse")), f3(val(c, "rgb_rmse"))]
        if labels:
            ids, ious = c.get("obj_ids", []), c.get("obj_iou", [])
            obj = " / ".join(f3(v) for v in ious)
            if len(ids) == 1:
                obj += " (obj %d)" % ids[0]
            elif ids:
                obj += " (obj %s)" % " / ".join(str(i) for i in ids)
            row += [f3(val(c, "miou")), obj or "-"]
        row.append("%d / %d" % (c.get("entries_final", 0), c.get("entries_created", 0)))
        g = val(c, "growth") if c.get("second_pass") else None
        row.append("-" if g is None else ("0%" if round(100 * g) == 0 else "%+d%%" % round(100 * g)))
        ns, fr = val(c, "never_seen_frac"), val(c, "free_frac")
        cell = "-" if ns is None else "%.2f" % ns
        if fr:
            cell += " (free %.2f)" % fr
        row.append(cell)
        out.append("| " + " | ".join(row) + " |")
    return out


def t_sets(t, d):
    """One row per (labelled set, model) of one `sooc3d eval --json` file holding several sequences."""
    cells = {}
    for r in t["rows"]:
        f = r[2] if len(r) > 2 else t["file"]
        if f not in cells:
            cells[f] = load(os.path.join(d, f)).get("cells", [])
    out = ["| set | objects | row | mean per-object IoU | IoU per object (id) | entries per object | depth RMSE (m) |",
           "|---|---:|---|---:|---|---:|---:|"]
    for set_label, seq in t["sets"]:
        for i, r in enumerate(t["rows"]):
            label, name, f = r[0], r[1], r[2] if len(r) > 2 else t["file"]
            c = next((cc for cc in cells[f] if cc.get("model") == name and cc.get("sequence") == seq), None)
            if c is None:
                raise SystemExit("results.sh: %s has no cell of model '%s' on '%s'" % (f, name, seq))
            ids, ious = c.get("obj_ids", []), c.get("obj_iou", [])
            mean = sum(ious) / len(ious) if ious else None
            per = ", ".join("%s (%d)" % (f3(v), k) for v, k in zip(ious, ids)) or "-"
            epo = "%.1f" % (c.get("entries_final", 0) / len(ids)) if ids else "-"
            out.append("| %s | %s | %s | %s | %s | %s | %s |" % (set_label if i == 0 else "", len(ids) if i == 0 else "",
                                                           label, f3(mean), per, epo, f3(val(c, "depth_rmse"))))
    return out


def t_bench(t, d):
    out = ["| figure | value |", "|---|---:|"]
    for label, f, key, fmt in t["rows"]:
        j = load(os.path.join(d, f))
        keys = key if isinstance(key, tuple) else (key,)
        vs = [j.get(k) for k in keys]
        if any(v is None for v in vs):
            s = "-"
        elif fmt == "pct":
            s = "%.1f%%" % (100 * vs[0])
        elif fmt == "us_ms":
            s = "%.2f ms" % (vs[0] / 1000.0)
        else:
            s = fmt.format(*vs)
        out.append("| %s | %s |" % (label, s))
    return out


KINDS = dict(matrix=t_matrix, composition=t_composition, rows=t_rows, ftrows=t_ftrows, real=t_real, sets=t_sets,
             bench=t_bench)


def files_of(t):
    fs = list(t.get("files", [])) + ([t["file"]] if "file" in t else [])
    for r in t.get("rows", []):
        if t["kind"] == "ftrows":
            fs += r[1]
        elif t["kind"] in ("real", "bench"):
            fs.append(r[1])
        elif t["kind"] == "sets":
            break
    return sorted(set(fs))


def render(name, d):
    t = TABLES[name]
    return KINDS[t["kind"]](t, d)


BEGIN = re.compile(r"^<!-- results\.sh: ([A-Za-z0-9_]+) -->$")
END = "<!-- end results.sh -->"


def blocks(lines):
    out, i = [], 0
    while i < len(lines):
        m = BEGIN.match(lines[i])
        if m:
            j = i + 1
            while j < len(lines) and lines[j] != END:
                j += 1
            if j == len(lines):
                raise SystemExit("results.sh: %s:%d: no '%s' after the table" % (DOC, i + 1, END))
            out.append((m.group(1), i, j))
            i = j
        i += 1
    return out


def main(argv):
    if argv and argv[0] in ("-h", "--help"):
        head = open("scripts/results.sh").read().split("\nset -euo")[0].split("\n")[1:]
        print("\n".join(l[2:] if l.startswith("# ") else l.lstrip("#") for l in head))
        return 0
    if argv and argv[0] == "--list":
        for n in TABLES:
            print("%-18s %s" % (n, " ".join(files_of(TABLES[n]))))
        return 0
    if argv and argv[0] == "--print":
        if len(argv) < 2 or argv[1] not in TABLES:
            raise SystemExit("results.sh --print NAME [DIR]: NAME is one of " + ", ".join(TABLES))
        print("\n".join(render(argv[1], argv[2] if len(argv) > 2 else "out/results")))
        return 0
    lines = open(DOC, encoding="utf-8").read().split("\n")
    if argv and argv[0] == "--check":
        bad = [n for n, _, _ in blocks(lines) if n not in TABLES]
        for n in bad:
            print("results.sh: %s names an unknown table '%s'" % (DOC, n))
        print("results.sh: %d tables in %s, %d unknown" % (len(blocks(lines)), DOC, len(bad)))
        return 1 if bad else 0
    d = argv[0] if argv else "out/results"
    done, kept = [], []
    for name, i, j in reversed(blocks(lines)):
        if name not in TABLES:
            raise SystemExit("results.sh: %s:%d: unknown table '%s'" % (DOC, i + 1, name))
        missing = [f for f in files_of(TABLES[name]) if not os.path.isfile(os.path.join(d, f))]
        if missing:
            kept.append("%s (no %s)" % (name, ", ".join(missing)))
            continue
        lines[i + 1:j] = render(name, d)
        done.append(name)
    if done:
        tmp = DOC + ".tmp.results"
        with open(tmp, "w", encoding="utf-8") as f:
            f.write("\n".join(lines))
        os.replace(tmp, DOC)
    print("results.sh: %s: rewrote %d table%s%s" % (DOC, len(done), "" if len(done) == 1 else "s",
                                                      (": " + ", ".join(reversed(done))) if done else ""))
    for k in reversed(kept):
        print("results.sh: kept %s" % k)
    return 0


sys.exit(main(sys.argv[1:]))
PY

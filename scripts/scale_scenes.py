# Experiment tool (models/experiments/README.md "Tabletops"): a copy of a folder of generated scenes
# seen at S times their size. Each scene's calib.yaml depth_scale, groundtruth.txt camera translations
# and scene.yaml clip_depth are multiplied by S; every other file is a symlink to the original. Object
# poses in scene.yaml are not scaled, so L2 figures on the copy are meaningless; masks and depth are.
#   python3 scripts/scale_scenes.py out/data/tabletop_val_m out/data/tabletop_val_m_x35 3.5
import os, sys, re
S = float(sys.argv[3]); src, dst = sys.argv[1], sys.argv[2]
os.makedirs(dst, exist_ok=True)
for sc in sorted(os.listdir(src)):
    a, b = os.path.join(src, sc), os.path.join(dst, sc)
    if not os.path.isdir(a): continue
    os.makedirs(b, exist_ok=True)
    for f in os.listdir(a):
        if f in ("calib.yaml", "groundtruth.txt", "scene.yaml"): continue
        if not os.path.exists(os.path.join(b, f)): os.symlink(os.path.abspath(os.path.join(a, f)), os.path.join(b, f))
    t = open(os.path.join(a, "calib.yaml")).read()
    t = re.sub(r"depth_scale: ([0-9.eE+-]+)", lambda m: "depth_scale: %.17g" % (float(m.group(1)) * S), t)
    open(os.path.join(b, "calib.yaml"), "w").write(t)
    out = []
    for line in open(os.path.join(a, "groundtruth.txt")):
        if line.startswith("#") or not line.strip(): out.append(line); continue
        v = line.split(); 
        for i in (1, 2, 3): v[i] = "%.9g" % (float(v[i]) * S)
        out.append(" ".join(v) + "\n")
    open(os.path.join(b, "groundtruth.txt"), "w").writelines(out)
    y = open(os.path.join(a, "scene.yaml")).read()
    y = re.sub(r"clip_depth: ([0-9.]+)", lambda m: "clip_depth: %g" % (float(m.group(1)) * S), y)
    open(os.path.join(b, "scene.yaml"), "w").write(y)

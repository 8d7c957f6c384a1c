#!/usr/bin/env python3
"""Cut a part out of a 7-Scenes style recording, with its poses in a given world frame.

    python3 scripts/split_recording.py --seq ../shared/real/7scenes_redkitchen \
        --world out/real_split/full/map.json --frames 300:600 --out out/real_split/second

Frames whose number n satisfies a <= n < b are kept: their colour and depth images are
linked (never copied), their poses (frame-%06d.pose.txt, camera-to-world) are written
premultiplied by the world frame T_world_src of a map.json written by `sooc3d infer`,
so that every part lies in the frame of the whole recording (+y up, the support plane at
y = 0); read them with `--world identity`. The gravity file is left out (the poses are
+y up already); the intrinsics file and the licence files are linked.
"""
import argparse
import json
import os
import re
import sys

FRAME = re.compile(r"^frame-(\d{6})\.(color\.jpg|color\.png|depth\.png|pose\.txt)$")


def fail(msg):
    print(f"split_recording: {msg}", file=sys.stderr)
    sys.exit(2)


def matmul(a, b):
    return [[sum(a[i][k] * b[k][j] for k in range(4)) for j in range(4)] for i in range(4)]


def read_pose(path):
    try:
        with open(path) as f:
            v = [float(x) for x in f.read().split()]
    except (OSError, ValueError) as e:
        fail(f"{path}: {e}")
    if len(v) != 16:
        fail(f"{path}: expected 16 numbers (a 4x4 pose), found {len(v)}")
    return [v[4 * i:4 * i + 4] for i in range(4)]


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--seq", required=True, help="the recording (7-Scenes layout)")
    ap.add_argument("--world", required=True, help="map.json of `sooc3d infer` on the whole recording")
    ap.add_argument("--frames", required=True, help="A:B, frame numbers A <= n < B")
    ap.add_argument("--out", required=True, help="the part's folder (made; existing links and poses replaced)")
    a = ap.parse_args()
    try:
        lo, hi = (int(x) for x in a.frames.split(":"))
    except ValueError:
        fail(f"--frames: expected A:B, got '{a.frames}'")
    if not 0 <= lo < hi:
        fail(f"--frames: expected 0 <= A < B, got '{a.frames}'")
    try:
        with open(a.world) as f:
            t = json.load(f)["world"]["T_world_src"]
    except (OSError, ValueError, KeyError, TypeError) as e:
        fail(f"{a.world}: no world frame (world.T_world_src): {e}")
    if len(t) != 16:
        fail(f"{a.world}: world.T_world_src has {len(t)} numbers, expected 16")
    W = [t[4 * i:4 * i + 4] for i in range(4)]
    seq = os.path.abspath(a.seq)
    if not os.path.isdir(seq):
        fail(f"{a.seq}: not a folder")
    os.makedirs(a.out, exist_ok=True)
    kept = set()
    for name in sorted(os.listdir(seq)):
        src = os.path.join(seq, name)
        dst = os.path.join(a.out, name)
        m = FRAME.match(name)
        if m:
            n = int(m.group(1))
            if not lo <= n < hi:
                continue
            kept.add(n)
        elif name == "gravity-direction.txt" or not os.path.isfile(src):
            continue
        if os.path.lexists(dst):
            os.remove(dst)
        if m and m.group(2) == "pose.txt":
            P = matmul(W, read_pose(src))
            tmp = dst + ".tmp"
            with open(tmp, "w") as f:
                for row in P:
                    f.write(" ".join(f"{x:.9e}" for x in row) + "\n")
            os.replace(tmp, dst)
        else:
            os.symlink(src, dst)
    if not kept:
        fail(f"{a.seq}: no frame numbered in {lo}:{hi}")
    print(f"split_recording: {len(kept)} frames ({min(kept)}..{max(kept)}) of {a.seq} in {a.out}")


if __name__ == "__main__":
    main()

#!/usr/bin/env python3
"""Every launch-file snippet shown in README.md and docs/*.md parses as the node reads it.

A snippet is a fenced ```yaml block whose top-level keys are launch sections, or an inline code span that
starts with a launch section ("`world: {floor: estimate}`"). Each is completed with the sections it does not
give (a replay sensor) and checked with `sooc3d node FILE --print-config`, which validates every key and
value as a run would, without starting anything.

  check_launch_keys.py REPO_ROOT SOOC_BIN
  check_launch_keys.py --selftest SOOC_BIN      (a snippet with an unknown key must be caught)
"""
import os
import re
import subprocess
import sys
import tempfile

SECTIONS = ("sensor", "pose", "calib", "model", "keyframe", "shm", "map", "world", "pipeline", "log", "view",
            "record", "odometry")
BASE = {"sensor": "sensor: {driver: replay, path: /nonexistent}"}
FENCE = re.compile(r"```yaml\n(.*?)```", re.S)
INLINE = re.compile(r"`((?:%s): [^`\n]+)`" % "|".join(SECTIONS))
TOPKEY = re.compile(r"^([a-z_]+):", re.M)
DOTTED = re.compile(r"^\w+: \w+: ")


def snippets(path):
    text = open(path, encoding="utf-8").read()
    for m in FENCE.finditer(text):
        body = m.group(1)
        keys = TOPKEY.findall(body)
        if keys and all(k in SECTIONS for k in keys):
            yield text.count("\n", 0, m.start()) + 2, body
    for m in INLINE.finditer(text):
        if DOTTED.match(m.group(1)):   # "model: unit_m: U": a key path of a training config, not a snippet
            continue
        yield text.count("\n", 0, m.start()) + 1, m.group(1) + "\n"


def check(bin_, where, body):
    keys = set(TOPKEY.findall(body))
    doc = body + "".join(v + "\n" for k, v in BASE.items() if k not in keys)
    with tempfile.NamedTemporaryFile("w", suffix=".yaml", delete=False) as f:
        f.write(doc)
        name = f.name
    try:
        r = subprocess.run([bin_, "node", name, "--print-config"], capture_output=True, text=True, timeout=60)
    finally:
        os.unlink(name)
    if r.returncode != 0:
        err = r.stderr.strip().splitlines()
        return "%s: launch snippet does not parse: %s\n    %s" % (where, err[-1] if err else "exit %d" % r.returncode,
                                                             body.strip().replace("\n", "\n    "))
    return None


def main():
    if len(sys.argv) == 3 and sys.argv[1] == "--selftest":
        bad = check(sys.argv[2], "selftest", "sensor: {driver: v4l2, device: /dev/video0}\n")
        good = check(sys.argv[2], "selftest", "world: {floor: estimate}\n")
        ok = bad is not None and good is None
        print("selftest: an unknown key is %s, a valid snippet %s" % ("caught" if bad else "MISSED",
                                                                       "passes" if not good else "FAILS"))
        return 0 if ok else 1
    root, bin_ = sys.argv[1], sys.argv[2]
    # docs/model.md and docs/training.md describe the model's and the trainer's configuration files,
    # whose sections share names with the launch file's
    skip = ("model.md", "training.md")
    files = [os.path.join(root, "README.md")] + sorted(
        os.path.join(root, "docs", f) for f in os.listdir(os.path.join(root, "docs")) if f.endswith(".md") and f not in skip)
    n, bad = 0, []
    for p in files:
        for line, body in snippets(p):
            n += 1
            e = check(bin_, "%s:%d" % (os.path.relpath(p, root), line), body)
            if e:
                bad.append(e)
    for e in bad:
        print(e)
    print("%d launch snippets in README.md and docs/, %d do not parse" % (n, len(bad)))
    return 1 if bad else 0


if __name__ == "__main__":
    sys.exit(main())

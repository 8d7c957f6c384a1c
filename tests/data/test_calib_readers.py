#!/usr/bin/python3
"""test_calib_readers: every calib/*.yaml reads back identically in the three
YAML readers a sooc3d user meets:

  - libyaml through sooc_calib_load (the node's loader; tests/data/calib_dump.c
    prints what it read as JSON, doubles at %.17g),
  - PyYAML (yaml.safe_load, python3-yaml),
  - OpenCV FileStorage (cv2, python3-opencv), the way docs/formats.md says to
    read it: scalars with .real()/.string(), matrices element by element
    (node["data"].at(i).real()), because the files use ROS camera_info maps,
    not !!opencv-matrix nodes, so .mat() does not apply.

OpenCV has no boolean type: `true`/`false` must read back as exactly the
strings "true"/"false" (a trailing comment once leaked into that string).
Numbers must be equal as doubles, strings equal, every key present in all
three. Interpretations the loader documents are applied before comparing:
all-zero distortion coefficients mean distortion_model "none".

  test_calib_readers.py <calib_dump> <calib dir>
Exit 0 pass, 1 fail, 77 skip (a Python module is missing).
"""
import glob
import json
import os
import subprocess
import sys

try:
    import yaml
except ImportError:
    print("test_calib_readers: PyYAML (python3-yaml) missing: skipped")
    sys.exit(77)
try:
    import cv2
except ImportError:
    print("test_calib_readers: OpenCV (python3-opencv) missing: skipped")
    sys.exit(77)

MATRICES = ("camera_matrix", "distortion_coefficients", "rectification_matrix",
            "projection_matrix", "T_color_depth", "T_effector_camera")
errors = []


def fail(msg):
    errors.append(msg)
    print("FAIL: " + msg)


def cv_value(node, key, where):
    """A scalar of a FileNode as a Python value (int, float, str)."""
    if node.isInt():
        return int(node.real())
    if node.isReal():
        return node.real()
    if node.isString():
        return node.string()
    fail("%s: %s: OpenCV node type %d is not a scalar" % (where, key, node.type()))
    return None


def cv_matrix(node, key, where):
    """A ROS-style {rows, cols, data} map read element by element."""
    m = {}
    for k in node.keys():
        sub = node.getNode(k)
        if k == "data":
            if not sub.isSeq():
                fail("%s: %s.data is not a sequence in OpenCV" % (where, key))
                continue
            m["data"] = [sub.at(i).real() for i in range(sub.size())]
        else:
            m[k] = cv_value(sub, key + "." + k, where)
    return m


def main():
    dump, calib_dir = sys.argv[1], sys.argv[2]
    files = sorted(glob.glob(os.path.join(calib_dir, "*.yaml")))
    if not files:
        fail("no calib/*.yaml in " + calib_dir)
    ours = subprocess.run([dump] + files, capture_output=True, text=True)
    if ours.returncode != 0:
        fail("calib_dump: " + ours.stderr.strip())
        return
    loaded = [json.loads(line) for line in ours.stdout.splitlines()]
    n_values = 0
    for path, lib in zip(files, loaded):
        where = os.path.basename(path)
        n_err = len(errors)
        with open(path) as f:
            py = yaml.safe_load(f)
        fs = cv2.FileStorage(path, cv2.FILE_STORAGE_READ)
        if not fs.isOpened():
            fail("%s: OpenCV cannot open it" % where)
            continue
        root = fs.root()
        cvkeys = list(root.keys())
        if sorted(cvkeys) != sorted(py.keys()):
            fail("%s: keys differ: OpenCV %s, PyYAML %s" % (where, cvkeys, list(py.keys())))
        for key, pv in py.items():
            node = root.getNode(key)
            if key in MATRICES:
                cm = cv_matrix(node, key, where)
                for k in set(pv) | set(cm):
                    if pv.get(k) != cm.get(k):
                        fail("%s: %s.%s: PyYAML %r, OpenCV %r" % (where, key, k, pv.get(k), cm.get(k)))
                data = pv["data"]
                if pv["rows"] * pv["cols"] != len(data):
                    fail("%s: %s: %dx%d but %d numbers" % (where, key, pv["rows"], pv["cols"], len(data)))
                if lib.get(key) != [float(x) for x in data]:
                    fail("%s: %s: loader %r, PyYAML %r" % (where, key, lib.get(key), data))
                for k in ("parent", "child"):
                    if k in pv and lib.get(key + "." + k) != pv[k]:
                        fail("%s: %s.%s: loader %r, PyYAML %r" % (where, key, k, lib.get(key + "." + k), pv[k]))
                n_values += len(data)
                continue
            cv = cv_value(node, key, where)
            if isinstance(pv, bool):
                want_cv = "true" if pv else "false"
                if cv != want_cv:
                    fail("%s: %s: PyYAML %r but OpenCV %r (OpenCV must read the string %r)"
                         % (where, key, pv, cv, want_cv))
            elif pv != cv or type(pv) is not type(cv):
                fail("%s: %s: PyYAML %r, OpenCV %r" % (where, key, pv, cv))
            lv = lib.get(key)
            if key == "distortion_model" and not any(py.get("distortion_coefficients", {}).get("data", [])):
                pv = "none"  # the loader's documented rule: all-zero coefficients mean none
            if lv != pv or (isinstance(pv, (int, float)) and float(lv) != float(pv)):
                fail("%s: %s: loader %r, PyYAML %r" % (where, key, lv, pv))
            n_values += 1
        if len(errors) == n_err:
            print("%s: %d keys, identical in libyaml (sooc_calib_load), PyYAML and OpenCV"
                  % (where, len(py)))
    print("%d files, %d values compared" % (len(files), n_values))


if __name__ == "__main__":
    main()
    if errors:
        print("test_calib_readers: %d mismatches" % len(errors))
        sys.exit(1)
    print("test_calib_readers: ok")

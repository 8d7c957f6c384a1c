#!/usr/bin/python3
"""Stack panel PNGs (sooc3d eval --panels, sooc3d render) into one figure, each under a caption.

    scripts/stack_panels.py OUT.png "caption=path/to/panel.png" ["caption=..." ...]

Used for the README's figures (docs/img/real_7scenes_ft_panels.png: see README "Real data").
Needs Debian's python3-opencv (scripts/install-deps.sh)."""
import sys

import cv2
import numpy as np


def main(argv):
    if len(argv) < 3 or any("=" not in a for a in argv[2:]):
        sys.stderr.write(__doc__)
        return 2
    rows, width = [], 0
    for arg in argv[2:]:
        cap, path = arg.split("=", 1)
        im = cv2.imread(path, cv2.IMREAD_COLOR)
        if im is None:
            sys.stderr.write("stack_panels: %s: not a readable image\n" % path)
            return 1
        width = max(width, im.shape[1])
        rows.append((cap, im))
    out = []
    for cap, im in rows:
        pad = np.full((im.shape[0], width - im.shape[1], 3), 255, np.uint8)
        lab = np.full((16, width, 3), 255, np.uint8)
        cv2.putText(lab, cap, (3, 12), cv2.FONT_HERSHEY_SIMPLEX, 0.4, (0, 0, 0), 1, cv2.LINE_AA)
        out += [lab, np.hstack([im, pad])]
    if not cv2.imwrite(argv[1], np.vstack(out)):
        sys.stderr.write("stack_panels: %s: cannot write\n" % argv[1])
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv))

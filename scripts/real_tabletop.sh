#!/usr/bin/env bash
# The real-tabletop table (docs/results.md "Real tabletops"): the shipped tabletop model online, online
# segmented by its entries' observed surfaces, and finetuned (SOOC3D+), and the geometric baseline, on
# every labelled real tabletop set, with a panel
# per held-out query frame and one figure per set (frame, and each row's segmentation).
#
#   bash scripts/real_tabletop.sh [OUT]        (default out/results; needs ../shared/real)
#
# Writes OUT/real_tabletop.json and OUT/real_tabletop_surfaces.json (sooc3d eval --json),
# OUT/real_tabletop.md, OUT/real_tabletop_panels/
# and OUT/real_tabletop_<set>.png. The APC labels are a network's predicted masks: its scores are
# agreement with them, not accuracy.
set -euo pipefail
cd "$(dirname "$0")/.."
OUT=${1:-out/results}
REAL=${SOOC_SHARED_REAL:-../shared/real}
BIN=${SOOC_BIN:-build/bin/sooc3d}
SETS=("$REAL/ycb_video/data/0000" "$REAL/label_fusion/data/labels" "$REAL/label_fusion/data/masks"
      "$REAL/apc_shelf/data/sample/scene-0000")
for s in "${SETS[@]}"; do
  [ -d "$s" ] || { echo "real_tabletop: $s is missing (the real sets live in ../shared/real)" >&2; exit 1; }
done
mkdir -p "$OUT"
rm -rf "$OUT/real_tabletop_panels"
"$BIN" eval --model models/sooc3d_tabletop/model.bin --baseline geometric --finetune --no-second-pass \
  --data "${SETS[@]}" --panels "$OUT/real_tabletop_panels" --json "$OUT/real_tabletop.json" --md "$OUT/real_tabletop.md"
# the online map segmented by its entries' observed surfaces, with the proposals and the support
# (docs/geometric.md "The entries' observed surfaces")
"$BIN" eval --model models/sooc3d_tabletop/model.bin --name surfaces --no-second-pass \
  --prop-only --prop-join 0.01 --prop-logit 3 --merge 0.05 --geo-support 0.06 --surface --surface-fill \
  --data "${SETS[@]}" --panels "$OUT/real_tabletop_panels" --json "$OUT/real_tabletop_surfaces.json"
# one figure per set: the first query frame's panel of each row, stacked
for s in "${SETS[@]}"; do
  n=$(basename "$s")
  d="$OUT/real_tabletop_panels/$n"
  q=$(ls "$d/geometric" | grep '^query_.*\.png$' | head -1)
  /usr/bin/python3 scripts/stack_panels.py "$OUT/real_tabletop_$n.png" \
    "geometric (support plane + clustering)=$d/geometric/$q" \
    "online (sooc3d_tabletop)=$d/sooc3d_tabletop/$q" \
    "online, observed surfaces (proposals, support)=$d/surfaces/$q" \
    "SOOC3D+ (finetuned)=$d/sooc3d_tabletop+ft/$q"
done
echo "real_tabletop: wrote $OUT/real_tabletop.json, $OUT/real_tabletop_surfaces.json, $OUT/real_tabletop.md and the figures"

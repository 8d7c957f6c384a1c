#!/usr/bin/env bash
# Dataset recipe for the shipped unity model (models/sooc3d_unity/).
# Training: dense small and medium unity scenes, so that views often hold as
# many objects as the model has slots (models/sooc3d_unity/README.md).
# Validation and test use seeds never used in training.
#   bash scripts/make_datasets.sh [OUT_DIR]      (default out/data)
set -euo pipefail
cd "$(dirname "$0")/.."
OUT=${1:-out/data}
BIN=${SOOC3D:-build/bin/sooc3d}
gen() { "$BIN" gen --preset unity --no-sheet "$@"; }
gen --scale s --density 0.5  --scenes 800 --seed 1001 --out "$OUT/train_s"
gen --scale m --density 0.35 --scenes 400 --seed 1002 --out "$OUT/train_m"
gen --scale m --scenes 8  --seed 8001 --out "$OUT/val_m"
# Held-out test sets at the generator's default density (0.2 objects/m^2).
for sc in s m l xl; do
  gen --scale $sc --scenes 20 --seed 9001 --out "$OUT/test_$sc"
done
# diagnostic (models/experiments/README.md "Large scenes"): the same l rooms walked as densely per m² as m rooms
gen --scale l --views 180 --scenes 20 --seed 9001 --out "$OUT/test_l_v180"
# Tabletop sets (models/sooc3d_tabletop): TABLETOP=1 bash scripts/make_datasets.sh also writes
# train/val/test tabletop scenes with Kinect sensor noise (docs/formats.md 5.1-5.2).
if [ "${TABLETOP:-0}" = 1 ]; then
  tt() { "$BIN" gen --preset tabletop --no-sheet "$@"; }
  tt --scale s --scenes 800 --seed 2001 --out "$OUT/tabletop_train_s"
  tt --scale m --scenes 400 --seed 2002 --out "$OUT/tabletop_train_m"
  tt --scale m --scenes 8   --seed 8002 --out "$OUT/tabletop_val_m"
  for sc in s m l; do
    tt --scale $sc --scenes 20 --seed 9002 --out "$OUT/tabletop_test_$sc"
  done
fi
# Tall-walled unity m rooms for room recordings (models/sooc3d_real): WALLS=1 bash scripts/make_datasets.sh.
if [ "${WALLS:-0}" = 1 ]; then
  gen --scale m --density 0.35 --walls 2.2,3.0 --scenes 400 --seed 1002 --out "$OUT/train_m_walls"
fi
# Blender sets (models/sooc3d_blender; the paper's Table 2): textured floors, shadows and specular highlights,
# same scales and densities as unity; BLENDER=1 bash scripts/make_datasets.sh.
if [ "${BLENDER:-0}" = 1 ]; then
  bl() { "$BIN" gen --preset blender --no-sheet "$@"; }
  bl --scale s --density 0.5  --scenes 800 --seed 3001 --out "$OUT/blender_train_s"
  bl --scale m --density 0.35 --scenes 400 --seed 3002 --out "$OUT/blender_train_m"
  bl --scale m --scenes 8 --seed 8003 --out "$OUT/blender_val_m"
  for sc in s m l xl; do
    bl --scale $sc --scenes 20 --seed 9003 --out "$OUT/blender_test_$sc"
  done
fi
echo "datasets in $OUT"

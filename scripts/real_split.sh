#!/usr/bin/env bash
# A part of a real scene the model was not adapted on (docs/results.md "A part of the kitchen
# the model was not adapted on"): the 7-Scenes redkitchen excerpt cut in two (frames 0-298 and
# 300-598, both in the whole recording's floor frame), sooc3d_real's recipe run on the first
# part only, then every model scored on the held-out frames of both parts, online and SOOC3D+.
#
#   bash scripts/real_split.sh [OUT]        (default out/real_split; about 1 h here)
#
# The models it trains go to OUT/train1 and OUT/train2 (kept: a second run only scores);
# the tables to OUT/*.json and the terminal.
set -euo pipefail
cd "$(dirname "$0")/.."
OUT=${1:-out/real_split}
BIN=${SOOC3D:-build/bin/sooc3d}
R=${SOOC_SHARED_REAL:-../shared/real}/7scenes_redkitchen
if [ ! -d "$R" ]; then
  echo "real_split: SKIP: $R not found (set SOOC_SHARED_REAL)" >&2
  exit 77
fi
[ -x "$BIN" ] || { echo "real_split: $BIN not built (cmake --build build)" >&2; exit 2; }
mkdir -p "$OUT"

# synthetic rooms of the recipe (models/sooc3d_real/README.md)
[ -d out/data/train_m_walls ] ||
  "$BIN" gen --preset unity --no-sheet --scale m --density 0.35 --walls 2.2,3.0 --scenes 400 --seed 1002 \
    --out out/data/train_m_walls
[ -d out/data/val_m ] || "$BIN" gen --preset unity --no-sheet --scale m --scenes 8 --seed 8001 --out out/data/val_m

# the whole recording's world frame: the support plane of its first 30 frames (the floor)
"$BIN" infer --model models/sooc3d_real/model.bin --seq "$R" --out "$OUT/full" --max-frames 30 --no-render
python3 scripts/split_recording.py --seq "$R" --world "$OUT/full/map.json" --frames 0:300 --out "$OUT/first"
python3 scripts/split_recording.py --seq "$R" --world "$OUT/full/map.json" --frames 300:600 --out "$OUT/second"

# sooc3d_real's two stages, on the first part only
D="--data $OUT/first out/data/train_m_walls --val out/data/val_m --world identity"
if [ ! -f "$OUT/train1/last.bin" ]; then
  OMP_WAIT_POLICY=passive nice -n 10 "$BIN" train --config models/sooc3d_real/config_stage1.yaml \
    --init models/sooc3d_unity/model.bin --max-seconds 2700 $D --out "$OUT/train1"
fi
if [ ! -f "$OUT/train2/last.bin" ]; then
  OMP_WAIT_POLICY=passive nice -n 10 "$BIN" train --config models/sooc3d_real/config.yaml \
    --init "$OUT/train1/last.bin" --max-seconds 2700 $D --out "$OUT/train2"
fi

# scored on the held-out frames of both parts (every 5th), online and SOOC3D+
E="--world identity --merge 0.35 --revisit --quiet"
"$BIN" eval --model models/sooc3d_unity/model.bin --name unity --data "$OUT/first" "$OUT/second" $E \
  --json "$OUT/unity.json"
for m in "models/sooc3d_real/model.bin real" "$OUT/train1/last.bin first-part-stage1" \
         "$OUT/train2/last.bin first-part"; do
  set -- $m
  "$BIN" eval --model "$1" --name "$2" --data "$OUT/first" "$OUT/second" $E \
    --finetune --ft-iterations 1500 --ft-lr-final 0.1 --json "$OUT/$2.json"
done

#!/usr/bin/env bash
# The main job, on a fresh Debian 12 machine:
#   1. install missing Debian packages (scripts/install-deps.sh),
#   2. build (Release, OpenMP) into build/,
#   3. render a unity medium scene with `sooc3d gen`,
#   4. if a shipped model exists: replay the scene through the node
#      (launch/replay_demo.yaml), printing the object table as it fills,
#      and draw the pictures from the stored map;
#   5. write everything to out/demo/ (scene, contact sheet, map.sqlite, PNGs).
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/install-deps.sh
cmake -S . -B build -DCMAKE_BUILD_TYPE=Release -DSOOC_OPENMP=ON >/dev/null
cmake --build build -j"$(nproc)"
BIN=build/bin/sooc3d
OUT=out/demo
mkdir -p "$OUT"
"$BIN" gen --preset unity --scale m --scenes 1 --seed 7 --out "$OUT/gen"
rm -rf "$OUT/scene" && cp -r "$OUT/gen/scene_0000" "$OUT/scene"
echo "demo: contact sheet at $OUT/gen/contact_sheet.png"
MODEL=models/sooc3d_unity/model.bin
if [ -f "$MODEL" ]; then
  rm -f "$OUT/map.sqlite" "$OUT/map.sqlite-wal" "$OUT/map.sqlite-shm"
  "$BIN" node launch/replay_demo.yaml --print-table
  "$BIN" render --model "$MODEL" --seq "$OUT/scene" --map "$OUT/map.sqlite" --out "$OUT/pictures"
  "$BIN" map list --db "$OUT/map.sqlite"
else
  echo "demo: no trained model at $MODEL yet; showing the synthetic data only"
fi
echo "demo: outputs in $OUT/"

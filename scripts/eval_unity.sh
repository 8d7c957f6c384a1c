#!/usr/bin/env bash
# The README's results table: the shipped unity model (and the global-frame
# baseline, when its weights exist) on held-out unity s/m/l/xl scenes
# (scripts/make_datasets.sh, seed 9001, never used in training), scored with a
# 5 m clip depth (docs/metrics.md "Clip depth"; CLIP=8 for the generator's full range).
#   bash scripts/eval_unity.sh [SCENES_PER_SCALE] [RUNS]     (defaults 20, 1)
#   env: SCALES="s m l xl", CLIP=5, SLOTS=0 (object slots per keyframe for SOOC3D;
#        0 = the model's K), OUT=out/eval/unity (OUT.json, OUT.md, OUT.log)
set -euo pipefail
cd "$(dirname "$0")/.."
N=${1:-20}
R=${2:-1}
BIN=${SOOC3D:-build/bin/sooc3d}
args=(--model models/sooc3d_unity/model.bin --name SOOC3D)
if [ -f models/baseline_global/model.bin ]; then
  args+=(--model models/baseline_global/model.bin --name global-frame)
fi
data=()
for sc in ${SCALES:-s m l xl}; do data+=("out/data/test_$sc"); done
OUT=${OUT:-out/eval/unity}
mkdir -p "$(dirname "$OUT")"
OMP_WAIT_POLICY=passive "$BIN" eval "${args[@]}" --data "${data[@]}" --scenes "$N" --runs "$R" \
  --clip "${CLIP:-5}" --slots "${SLOTS:-0}" --json "$OUT.json" --md "$OUT.md" --threads 2 2>&1 | tee "$OUT.log"

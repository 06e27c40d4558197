#!/usr/bin/env bash
# Polyhedral meshes on the H200 (issue 35): an octree of about 12M cells (a hex grid refined
# once inside a ball; the coarse cells beside refined ones are polyhedra) beside the hex mesh
# of a grid of the same size, on soft-bvh and rt-bvh (one box a cell): centres and random
# query rates and memory, from `tetloc bench` (JSON lines under $OUT), and `info` of each.
#
# Usage, from the repository root on the device machine:
#   OUT=... bash scripts/h200/poly.sh path/to/release/tetloc [CELLS]
set -u
BIN=$1
CELLS=${2:-12M}
. "$(dirname "$0")/common.sh"
gpu_setup "$BIN"
for mesh in "jets-octree:$CELLS" "jets-hex:$CELLS"; do
  name=${mesh%%:*}
  echo "== $mesh" | tee -a "$OUT/summary.txt"
  timeout 300 "$BIN" info "$mesh" > "$OUT/$name.info.txt" 2>&1
  timeout 900 "$BIN" bench "$mesh" --backend soft-bvh,rt-bvh --queries centers,random --n 10M --repeats 5 --json \
    > "$OUT/$name.bench.jsonl" 2> "$OUT/$name.bench.log"
  echo "   exit $? ($(wc -l < "$OUT/$name.bench.jsonl") rows)" | tee -a "$OUT/summary.txt"
done

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
OUT=${OUT:?set OUT to the folder for the logs}
mkdir -p "$OUT"
# The device machine's Vulkan loader, as scripts/gpu-march.sh sets it up.
if ls .gl/*.deb >/dev/null 2>&1; then
  for f in .gl/*.deb; do dpkg -x "$f" /; done
  ldconfig
fi
{ date -u; nvidia-smi --query-gpu=name,driver_version,memory.total --format=csv; } > "$OUT/gpu.txt" 2>&1
if ! timeout 30 "$BIN" devices >> "$OUT/gpu.txt" 2>&1; then
  export VK_DRIVER_FILES=/usr/local/nvidia/share/vulkan/icd.d/nvidia_icd.json
  echo "retrying with VK_DRIVER_FILES=$VK_DRIVER_FILES" >> "$OUT/gpu.txt"
  timeout 30 "$BIN" devices >> "$OUT/gpu.txt" 2>&1
fi
for mesh in "jets-octree:$CELLS" "jets-hex:$CELLS"; do
  name=${mesh%%:*}
  echo "== $mesh" | tee -a "$OUT/summary.txt"
  timeout 300 "$BIN" info "$mesh" > "$OUT/$name.info.txt" 2>&1
  timeout 900 "$BIN" bench "$mesh" --backend soft-bvh,rt-bvh --queries centers,random --n 10M --repeats 5 --json \
    > "$OUT/$name.bench.jsonl" 2> "$OUT/$name.bench.log"
  echo "   exit $? ($(wc -l < "$OUT/$name.bench.jsonl") rows)" | tee -a "$OUT/summary.txt"
done

#!/usr/bin/env bash
# The browser viewer's speed (issue 31) on the H200: `tetloc view` serves over loopback and
# the hidden `tetloc view-bench` client orbits the camera continuously (120 input events a
# second), receives and decodes every frame, acknowledges each as the page does, and after
# each orbit stops and waits for the lossless still frame. Reported per case (JSON under
# $OUT): delivered frames/s while moving, input-to-frame latency, still-frame latency, and
# the split of a frame's time: march, encode, send, decode (+ every frame in a CSV).
# Targets at agulhas 36M, 1024²: ≥ 60 frames/s, ≤ 50 ms input to frame, still ≤ 150 ms.
#
# Usage, from the repository root on the device machine:
#   OUT=... bash scripts/h200/view.sh path/to/release/tetloc [BUDGET_S]
# agulhas 36M is written by `tetloc gen` and read back as a file; japan 62M and jets 250M
# (compact preset) are generated in memory (SHAPE:N) to stay within the time budget.
set -u
BIN=$1
BUDGET=${2:-540}
START=$SECONDS
. "$(dirname "$0")/common.sh"
gpu_setup "$BIN" name,driver_version,clocks.sm,clocks.max.sm

# case NAME MESH SIZE SECONDS_PER_ORBIT [view options...]
case_() {
  local name=$1 mesh=$2 size=$3 orbit=$4
  shift 4
  view_case "$name" "$mesh" --field f --size "$size" --backend soft-bvh "$@" || return
  timeout $((BUDGET - (SECONDS - START))) "$BIN" view-bench "$view_url" --seconds "$orbit" --orbits 3 \
    --frames-csv "$OUT/$name.frames.csv" > "$OUT/$name.json" 2> "$OUT/$name.bench.log"
  echo "   bench exit $?" | tee -a "$OUT/summary.txt"
  view_stop
  cat "$OUT/$name.json" >> "$OUT/summary.txt"
}

mesh=/tmp/tetloc-view-agulhas-36M.vtu
if [ ! -s "$mesh" ]; then
  s0=$SECONDS
  "$BIN" gen agulhas --cells 36M -o "$mesh" > "$OUT/gen.log" 2>&1
  echo "== gen agulhas 36M: exit $? after $((SECONDS - s0)) s" | tee -a "$OUT/summary.txt"
fi
case_ agulhas-36M-1024 "$mesh" 1024x1024 6
case_ agulhas-36M-512 "$mesh" 512x512 4
case_ japan-62M-1024 japan:62M 1024x1024 4
case_ jets-250M-compact-1024 jets:250M 1024x1024 4 --preset compact
cat "$OUT/gpu.txt"

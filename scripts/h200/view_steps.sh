#!/usr/bin/env bash
# The viewer moving through time on a GPU machine: `tetloc view SERIES` serves over loopback
# and the hidden `tetloc view-bench --time-steps 2` client plays the series twice, each step
# sent as a stop and waited for until its still frame (what the page's play button does);
# then an orbit of the same view for the still frame of a step that does not change.
# Reported per case (JSON under $OUT): step-to-still-frame latency and steps shown a second.
#
# Usage, from the repository root on the device machine:
#   OUT=... bash scripts/h200/view_steps.sh path/to/release/tetloc [BUDGET_S]
# The series: `tetloc gen fusion` written once and copied as each step's .vtu (the same
# values at every step; each step is still its own file, read, validated and located anew).
set -u
BIN=$1
BUDGET=${2:-540}
START=$SECONDS
. "$(dirname "$0")/common.sh"
gpu_setup "$BIN" name,driver_version,clocks.sm,clocks.max.sm

# series NAME TETS STEPS: /tmp/steps-NAME.pvd over STEPS copies of a generated fusion mesh.
series() {
  local name=$1 tets=$2 steps=$3 dir=/tmp/steps-$1
  mkdir -p "$dir"
  [ -s "$dir/s_0.vtu" ] || "$BIN" gen fusion --tets "$tets" -o "$dir/s_0.vtu" -q
  local lines=""
  for k in $(seq 0 $((steps - 1))); do
    [ -s "$dir/s_$k.vtu" ] || cp "$dir/s_0.vtu" "$dir/s_$k.vtu"
    lines="$lines<DataSet timestep=\"$k\" file=\"s_$k.vtu\"/>"
  done
  echo "<?xml version=\"1.0\"?><VTKFile type=\"Collection\" version=\"0.1\"><Collection>$lines</Collection></VTKFile>" > "$dir/series.pvd"
}

# case NAME PVD SIZE BACKEND
case_() {
  local name=$1 pvd=$2 size=$3 backend=$4
  local left=$((BUDGET - (SECONDS - START)))
  if [ "$left" -lt 60 ]; then echo "== $name: skipped (budget)" | tee -a "$OUT/summary.txt"; return; fi
  echo "== $name: view $pvd --size $size --backend $backend" | tee -a "$OUT/summary.txt"
  local s0=$SECONDS
  "$BIN" view "$pvd" --field f --size "$size" --port 0 --backend "$backend" > "$OUT/$name.url" 2> "$OUT/$name.server.log" &
  local pid=$!
  while [ ! -s "$OUT/$name.url" ] && kill -0 "$pid" 2>/dev/null && [ $((SECONDS - START)) -lt "$BUDGET" ]; do sleep 1; done
  if [ ! -s "$OUT/$name.url" ]; then
    echo "   no URL (see $name.server.log)" | tee -a "$OUT/summary.txt"
    kill -INT "$pid" 2>/dev/null; wait "$pid"
    return
  fi
  echo "   ready after $((SECONDS - s0)) s" | tee -a "$OUT/summary.txt"
  local url
  url=$(head -1 "$OUT/$name.url")
  timeout $((BUDGET - (SECONDS - START))) "$BIN" view-bench "$url" --time-steps 2 > "$OUT/$name.steps.json" 2> "$OUT/$name.bench.log"
  echo "   steps exit $?" | tee -a "$OUT/summary.txt"
  timeout $((BUDGET - (SECONDS - START))) "$BIN" view-bench "$url" --seconds 2 --orbits 3 > "$OUT/$name.orbit.json" 2>> "$OUT/$name.bench.log"
  echo "   orbit exit $?" | tee -a "$OUT/summary.txt"
  kill -INT "$pid"
  wait "$pid"
  cat "$OUT/$name.steps.json" >> "$OUT/summary.txt"
  grep -A6 '"still_ms"' "$OUT/$name.orbit.json" >> "$OUT/summary.txt"
}

series 1.4M 1.4M 6
case_ fusion-1.4M-soft-bvh /tmp/steps-1.4M/series.pvd 1024x1024 soft-bvh
case_ fusion-1.4M-cpu /tmp/steps-1.4M/series.pvd 1024x1024 cpu
series 12M 12M 4
case_ fusion-12M-soft-bvh /tmp/steps-12M/series.pvd 1024x1024 soft-bvh
cat "$OUT/gpu.txt"

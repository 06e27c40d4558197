#!/usr/bin/env bash
# The viewer moving through time: `tetloc view SERIES` serves over loopback and the hidden
# `tetloc view-bench --time-steps 2` client plays the series twice, each step sent as a stop
# and waited for until its still frame (what the page's play button does); then an orbit of
# the same view for the still frame of a step that does not change. Reported per case (JSON
# under $OUT): step-to-still-frame latency and steps shown a second.
#
# Usage, from the repository root (on the device machine, or on any machine with BACKEND=cpu):
#   OUT=... [BACKEND=soft-bvh] [SIZE=1024x1024] [MESHES="1.4M:6 12M:4"] \
#     bash scripts/h200/view_steps.sh path/to/release/tetloc [BUDGET_S]
# MESHES: TETS:STEPS for each series: `tetloc gen fusion --tets TETS` written once and copied
# as each step's .vtu (the same values at every step; each step is still its own file, read,
# validated and located anew), indexed by a .pvd.
set -u
BIN=$1
BUDGET=${2:-540}
BACKEND=${BACKEND:-soft-bvh}
SIZE=${SIZE:-1024x1024}
MESHES=${MESHES:-1.4M:6 12M:4}
START=$SECONDS
. "$(dirname "$0")/common.sh"
mkdir -p "$OUT"
if command -v nvidia-smi > /dev/null; then gpu_setup "$BIN" name,driver_version,clocks.sm,clocks.max.sm; fi

for case in $MESHES; do
  tets=${case%%:*} steps=${case##*:} dir=/tmp/tetloc-view-steps-${case%%:*}
  mkdir -p "$dir"
  [ -s "$dir/s_0.vtu" ] || "$BIN" gen fusion --tets "$tets" -o "$dir/s_0.vtu" -q
  lines=""
  for k in $(seq 0 $((steps - 1))); do
    [ -s "$dir/s_$k.vtu" ] || cp "$dir/s_0.vtu" "$dir/s_$k.vtu"
    lines="$lines<DataSet timestep=\"$k\" file=\"s_$k.vtu\"/>"
  done
  echo "<?xml version=\"1.0\"?><VTKFile type=\"Collection\" version=\"0.1\"><Collection>$lines</Collection></VTKFile>" > "$dir/series.pvd"
  name=fusion-$tets-$steps-$BACKEND
  view_case "$name" "$dir/series.pvd" --field f --size "$SIZE" --backend "$BACKEND" || continue
  timeout $((BUDGET - (SECONDS - START))) "$BIN" view-bench "$view_url" --time-steps 2 > "$OUT/$name.steps.json" 2> "$OUT/$name.bench.log"
  echo "   steps exit $?" | tee -a "$OUT/summary.txt"
  timeout $((BUDGET - (SECONDS - START))) "$BIN" view-bench "$view_url" --seconds 1 --orbits 3 > "$OUT/$name.orbit.json" 2>> "$OUT/$name.bench.log"
  echo "   orbit exit $?" | tee -a "$OUT/summary.txt"
  view_stop
  cat "$OUT/$name.steps.json" >> "$OUT/summary.txt"
  grep -A6 '"still_ms"' "$OUT/$name.orbit.json" >> "$OUT/summary.txt"
done

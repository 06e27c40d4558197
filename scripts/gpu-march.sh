#!/usr/bin/env bash
# Volume-rendering frame rates (the paper's Table 1, right-hand columns) of the GPU marcher,
# one device call: `tetloc render SHAPE:N --fps` per shape, each in its own process under a
# timeout, most important first, stopping before the time budget runs out.
# Usage, from the repository root on the device machine:
#   bash scripts/gpu-march.sh .devbin/tetloc-march "$OUT" [BUDGET_S]
set -u
BIN=$1
LOGS=$2
BUDGET=${3:-280}
START=$SECONDS
for f in .gl/*.deb; do dpkg -x "$f" /; done
ldconfig
{ date -u; nvidia-smi --query-gpu=name,driver_version,clocks.sm,clocks.max.sm,power.limit,temperature.gpu --format=csv; } > "$LOGS/gpu.txt" 2>&1
if ! timeout 30 "$BIN" devices >> "$LOGS/gpu.txt" 2>&1; then
  export VK_DRIVER_FILES=/usr/local/nvidia/share/vulkan/icd.d/nvidia_icd.json
  echo "retrying with VK_DRIVER_FILES=$VK_DRIVER_FILES" >> "$LOGS/gpu.txt"
  timeout 30 "$BIN" devices >> "$LOGS/gpu.txt" 2>&1
fi
# step SECONDS SPEC BACKENDS [PNG]
step() {
  local left=$((BUDGET - (SECONDS - START)))
  if [ "$left" -lt 20 ]; then echo "== $2 $3: skipped (budget)" >> "$LOGS/fps.log"; return; fi
  local t=$(( $1 < left ? $1 : left ))
  local out=()
  [ -n "${4:-}" ] && out=(--out "$LOGS/$4")
  echo "== $2 $3 (timeout $t s)" >> "$LOGS/fps.log"
  local s0=$SECONDS
  timeout "$t" "$BIN" render "$2" --field f --size 1024x1024 --fps 8 --backend "$3" "${out[@]}" >> "$LOGS/fps.log" 2>&1
  echo "== exit $? after $((SECONDS - s0)) s" >> "$LOGS/fps.log"
}
step 60 fusion:3M soft-bvh,rt-bvh,rt-shared-faces,rt-rep-faces fusion.png
step 60 jets:36M soft-bvh jets.png
step 90 agulhas:36M soft-bvh,rt-bvh,rt-shared-faces,rt-rep-faces agulhas.png
step 60 jets:12M soft-bvh,rt-bvh,rt-shared-faces,rt-rep-faces
step 80 japan:62M soft-bvh,rt-bvh japan.png
cat "$LOGS/gpu.txt"
grep -E "^==|FPS|rror" "$LOGS/fps.log"

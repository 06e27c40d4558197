#!/usr/bin/env bash
# soft-bvh layout variants on the device (NOTES.md, "next measurement"): leaf size,
# workgroup size, pure-f32 test, each benchmark warmed up for 0.5 s first.
# Usage, from the repository root on the device machine, after building vkbench here and
# copying it to .devbin/ (carry .gl and .devbin):
#   bash crates/tetloc-vulkan/scripts/h100-softbvh.sh .devbin/vkbench "$OUT"
set -u
BIN=$1
LOGS=$2
TETS=${TETS:-12000000}
for f in .gl/*.deb; do dpkg -x "$f" /; done
ldconfig
{ date -u; nvidia-smi --query-gpu=name,driver_version,clocks.sm,power.draw --format=csv; } > "$LOGS/gpu.txt" 2>&1
timeout 400 "$BIN" --tets "$TETS" --kernels soft-bvh --variants --modes uniform,random,bbox --check 1000000 --repeats 7 > "$LOGS/softbvh.log" 2>&1
echo "exit $?" >> "$LOGS/gpu.txt"
timeout 150 "$BIN" --tets "$TETS" --kernels rt-bvh,rt-shared-faces --modes uniform,random --check 0 --repeats 7 > "$LOGS/rt.log" 2>&1
echo "rt exit $?" >> "$LOGS/gpu.txt"
cat "$LOGS/gpu.txt"
grep -h -E "check of|build failed|Error" "$LOGS"/*.log
for f in "$LOGS"/softbvh.log "$LOGS"/rt.log; do sed -n '/^config/,/^memory/p' "$f" | grep -v '^memory'; done

#!/usr/bin/env bash
# One device call's worth of measurements (see docs/design/kernels.md): a 12M-tet jets mesh through every
# kernel (checked against the CPU, then benchmarked), and soft-bvh layout variants.
# Usage, from the repository root on the device machine:
#   bash scripts/gpu-kernels.sh .devbin/vkbench "$OUT"
# Each kernel runs in its own process under a timeout, so that one failure loses one log.
set -u
BIN=$1
LOGS=$2
TETS=${TETS:-12000000}
for f in .gl/*.deb; do dpkg -x "$f" /; done
ldconfig
{ date -u; nvidia-smi --query-gpu=name,driver_version,clocks.sm,clocks.max.sm,power.draw,power.limit,temperature.gpu --format=csv; } > "$LOGS/gpu.txt" 2>&1
probe() { timeout 60 "$BIN" --tets 20000 --check 20000 --modes uniform --repeats 5 > "$LOGS/probe.log" 2>&1; }
if ! probe; then
  export VK_DRIVER_FILES=/usr/local/nvidia/share/vulkan/icd.d/nvidia_icd.json
  echo "retrying with VK_DRIVER_FILES=$VK_DRIVER_FILES" >> "$LOGS/gpu.txt"
  if ! probe; then
    # Say why no driver was found, then give up.
    { ls -l /usr/local/nvidia/share/vulkan/icd.d/ /usr/share/vulkan/icd.d/ /etc/vulkan/icd.d/ 2>&1
      cat /usr/local/nvidia/share/vulkan/icd.d/*.json
      lib=$(grep -ho '"library_path"[^,]*' /usr/local/nvidia/share/vulkan/icd.d/*.json | cut -d'"' -f4)
      ldd "$(ldconfig -p | grep -m1 "$lib" | awk '{print $NF}')"
      VK_LOADER_DEBUG=error,warn,driver "$BIN" --tets 1000 --check 0 --modes uniform --repeats 5; } >> "$LOGS/probe.log" 2>&1
    tail -n 60 "$LOGS/probe.log"
    exit 1
  fi
fi
for k in soft-bvh rt-bvh rt-shared-faces rt-rep-faces; do
  timeout 110 "$BIN" --tets "$TETS" --kernels "$k" --check 2000000 --field f --power --repeats 7 > "$LOGS/jets-$k.log" 2>&1
  echo "$k exit $?" >> "$LOGS/gpu.txt"
done
timeout 90 "$BIN" --tets "$TETS" --kernels soft-bvh --variants --modes uniform,random --check 0 --repeats 7 > "$LOGS/variants.log" 2>&1
echo "variants exit $?" >> "$LOGS/gpu.txt"
cat "$LOGS/gpu.txt"
grep -h -E "check of|build failed|Error|error" "$LOGS"/*.log
for f in "$LOGS"/jets-*.log "$LOGS"/variants.log; do sed -n '/^config/,/^memory/p' "$f" | grep -v '^memory'; done
grep -h -A6 '^memory' "$LOGS"/jets-*.log | grep -E 'final'

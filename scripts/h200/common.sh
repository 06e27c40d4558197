# Shared by the scripts/h200/*.sh runs (sourced, not run).

# gpu_setup BIN GPU_TXT [NVIDIA_SMI_QUERY]: the device machine's Vulkan loader (the .gl/*.deb
# packages unpacked, as scripts/gpu-march.sh does), then the date, the card and `BIN devices`
# in GPU_TXT; where the loader finds no device, the NVIDIA ICD is named and asked again.
gpu_setup() {
  local bin=$1 txt=$2 query=${3:-name,driver_version,memory.total}
  if ls .gl/*.deb >/dev/null 2>&1; then
    for f in .gl/*.deb; do dpkg -x "$f" /; done
    ldconfig
  fi
  { date -u; nvidia-smi --query-gpu="$query" --format=csv; } > "$txt" 2>&1
  if ! timeout 30 "$bin" devices >> "$txt" 2>&1; then
    export VK_DRIVER_FILES=/usr/local/nvidia/share/vulkan/icd.d/nvidia_icd.json
    echo "retrying with VK_DRIVER_FILES=$VK_DRIVER_FILES" >> "$txt"
    timeout 30 "$bin" devices >> "$txt" 2>&1
  fi
}

# step NAME LIMIT_S COMMAND...: runs COMMAND under a time limit, its output in $out/NAME.log
# (the end of it echoed), and counts a failure in $failed.
step() {
  local name=$1 limit=$2
  shift 2
  echo "== $name (limit ${limit}s) $(date -u +%H:%M:%S)"
  timeout "$limit" "$@" > "$out/$name.log" 2>&1
  local rc=$?
  tail -n 30 "$out/$name.log"
  echo "== $name: exit $rc"
  [ "$rc" -eq 0 ] || failed=$((failed + 1))
}

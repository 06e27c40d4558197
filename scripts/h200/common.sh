# Shared by the scripts/h200/*.sh runs (sourced, not run).

# gpu_setup BIN [NVIDIA_SMI_QUERY]: the logs' folder $OUT made (the caller sets OUT), the
# device machine's Vulkan loader (the .gl/*.deb packages unpacked, as scripts/gpu-march.sh
# does), then the date, the card and `BIN devices` in $OUT/gpu.txt; where the loader finds no
# device, the NVIDIA ICD is named and asked again.
gpu_setup() {
  local bin=$1 query=${2:-name,driver_version,memory.total}
  local txt=${OUT:?set OUT to the folder for the logs}/gpu.txt
  mkdir -p "$OUT"
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

# wheel_setup NAME WHEEL: the start of the runs of a tetloc wheel under the machine's Python
# (torch.sh, zerocopy.sh). Sets out (from OUT, made; this shell's output goes to $out/NAME.log
# too), repo (two folders above the script), failed=0 (for step), work (a scratch folder), py
# (TETLOC_PY, else python3 with WHEEL on PYTHONPATH) and data (`--data DIR` where the oracle
# data is, else empty), and writes the card to $out/gpu.txt.
wheel_setup() {
  local name=$1 wheel=$2
  out=${OUT:?set OUT to the folder for the logs}
  mkdir -p "$out"
  repo=$(cd "$(dirname "$0")/../.." && pwd)
  exec > >(tee "$out/$name.log") 2>&1
  failed=0
  nvidia-smi --query-gpu=name,driver_version,memory.total,uuid --format=csv,noheader > "$out/gpu.txt" 2>&1
  cat "$out/gpu.txt"
  work=$(mktemp -d)
  if [ -n "${TETLOC_PY:-}" ]; then
    py=$TETLOC_PY
  else
    # The machine's python3 holds PyTorch and numpy (on the H200 image it is itself a virtualenv,
    # so a `--system-site-packages` venv made from it would not see them): the wheel's files go
    # into a folder of their own on PYTHONPATH.
    py=python3
    if ! python3 -m pip install -q --no-index --no-deps --no-compile --target "$work/site" "$wheel"; then
      echo "no pip: unpacking $wheel onto PYTHONPATH"
      python3 -c 'import sys, zipfile; zipfile.ZipFile(sys.argv[1]).extractall(sys.argv[2])' "$wheel" "$work/site" ||
        { echo "cannot unpack $wheel"; exit 1; }
    fi
    export PYTHONPATH=$work/site${PYTHONPATH:+:$PYTHONPATH}
  fi
  data=()
  [ -d "$repo/shared/data" ] && data=(--data "$repo/shared/data")
  [ -z "${data[*]}" ] && [ -d "$repo/../shared/data" ] && data=(--data "$repo/../shared/data")
}

# view_case NAME VIEW_ARGS...: `$BIN view VIEW_ARGS --port 0` in the background for the
# view scripts (BIN, OUT, START and BUDGET set by the caller): skipped with under 60 s of the
# budget left; returns 1 when no URL comes (the mesh is loaded and the locator built before
# it is printed). Otherwise the URL is in $view_url, the pid in $view_pid, and the case's
# lines go to $OUT/summary.txt; `view_stop` ends it.
view_case() {
  local name=$1
  shift
  if [ $((BUDGET - (SECONDS - START))) -lt 60 ]; then echo "== $name: skipped (budget)" | tee -a "$OUT/summary.txt"; return 1; fi
  echo "== $name: view $*" | tee -a "$OUT/summary.txt"
  local s0=$SECONDS
  "$BIN" view "$@" --port 0 > "$OUT/$name.url" 2> "$OUT/$name.server.log" &
  view_pid=$!
  while [ ! -s "$OUT/$name.url" ] && kill -0 "$view_pid" 2>/dev/null && [ $((SECONDS - START)) -lt "$BUDGET" ]; do sleep 1; done
  if [ ! -s "$OUT/$name.url" ]; then
    echo "   no URL (see $name.server.log)" | tee -a "$OUT/summary.txt"
    kill -INT "$view_pid" 2>/dev/null; wait "$view_pid"
    return 1
  fi
  view_url=$(head -1 "$OUT/$name.url")
  echo "   ready after $((SECONDS - s0)) s" | tee -a "$OUT/summary.txt"
}

# view_stop: Ctrl-C to the server of the last view_case, and its exit code in the summary.
view_stop() {
  kill -INT "$view_pid"
  wait "$view_pid"
  echo "   server exit $? (0: Ctrl-C ends it cleanly)" | tee -a "$OUT/summary.txt"
}

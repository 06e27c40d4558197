#!/usr/bin/env bash
# tetloc.torch's zero-copy path on a CUDA GPU (issue 33 item 2): CUDA memory and semaphores
# shared with Vulkan. Runs the CUDA checks (python/tests/cuda_zerocopy.py: the path is
# zero-copy, ids identical to the CPU backend and the host path, 0 host copies, non-finite
# points, a side stream, 10,000 sample calls with flat device memory, a mixed mesh refused)
# and the benchmark (python/benchmarks/bench_zerocopy.py: jets 12M, 16M CUDA points, locate,
# sample forward and backward G/s, zero-copy against the host path in one run). Logs and JSON
# under $OUT.
#
#   OUT=/some/dir scripts/h200/zerocopy.sh WHEEL TETLOC_BIN
#
# WHEEL: a tetloc wheel built with the `cuda` feature of tetloc-vulkan (python/Cargo.toml asks
# for it; maturin, abi3, x86-64); TETLOC_BIN: a release `tetloc` binary (for `tetloc gen`).
# As scripts/h200/torch.sh: the machine's python3 with its PyTorch, the wheel on PYTHONPATH,
# the machine's Vulkan loader and NVIDIA ICD (libcuda is loaded at run time by the wheel).
# Every step has its own time limit; the whole run stays under 9 minutes. Exit status: failed steps.
set -uo pipefail
wheel=${1:?usage: OUT=DIR scripts/h200/zerocopy.sh WHEEL TETLOC_BIN}
bin=${2:?usage: OUT=DIR scripts/h200/zerocopy.sh WHEEL TETLOC_BIN}
. "$(dirname "$0")/common.sh" # wheel_setup, step
wheel_setup zerocopy "$wheel"

"$py" - <<'PY' 2>&1 | tee "$out/versions.txt"
import sys, torch, tetloc, tetloc._tetloc as t
print("python", sys.version.split()[0], "torch", torch.__version__, "cuda", torch.version.cuda,
      "available", torch.cuda.is_available())
print("tetloc", tetloc.__version__, "CUDA driver loadable", t.cuda_driver_available())
print("Vulkan devices", [(d["name"], d["driver"]) for d in tetloc.devices()])
PY

small=$work/jets200k.vtu
step gen_jets200k 60 "$bin" gen jets --cells 200k -o "$small"
step zerocopy_checks 200 "$py" "$repo/python/tests/cuda_zerocopy.py" --mesh "$small" "${data[@]}" \
  --json "$out/zerocopy_checks.json"
# The same with the validation layer on, where the machine has it (TETLOC_VK_VALIDATION).
TETLOC_VK_VALIDATION=1 step zerocopy_checks_validated 120 "$py" "$repo/python/tests/cuda_zerocopy.py" \
  --mesh "$small" "${data[@]}" --leak-calls 100 --points 100000

mesh=${MESH:-$work/jets12M.vtu}
[ -f "$mesh" ] || step gen_jets12M 90 "$bin" gen jets --cells 12M -o "$mesh"
if [ -f "$mesh" ]; then
  step bench_zerocopy 240 "$py" "$repo/python/benchmarks/bench_zerocopy.py" "$mesh" --points "${POINTS:-16M}" \
    --repeats 3 --json "$out/bench_zerocopy.json"
fi
echo "== done $(date -u +%H:%M:%S): $failed failed step(s)"
exit "$failed"

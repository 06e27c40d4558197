#!/usr/bin/env bash
# tetloc.torch on a CUDA GPU (issue 33): the CUDA checks (python/tests/cuda_torch.py: ids and
# values as on the CPU, gradcheck on CUDA, bad input, host copies per call, 10,000 sample calls
# with flat device memory) and the benchmark (python/benchmarks/bench_torch.py: jets 12M from
# `tetloc gen`, 16M random CUDA points, sample forward and backward, against torch.cdist nearest
# vertex and grid_sample on a grid of the mesh's memory). Logs and JSON under $OUT.
#
#   OUT=/some/dir scripts/h200/torch.sh WHEEL TETLOC_BIN
#
# WHEEL: a tetloc wheel (maturin, abi3, x86-64); TETLOC_BIN: a release `tetloc` binary (for
# `tetloc gen`). Uses the machine's Python with its PyTorch (no network): the wheel goes into a
# folder on PYTHONPATH beside python3's own packages. Every step has its own time limit and the steps
# go on after a failure; the whole run stays under 9 minutes. Exit status: failed steps.
# For a dry run elsewhere: TETLOC_PY (a Python with tetloc and torch: no virtualenv),
# TORCH_DEVICE=cpu, POINTS (16M), MESH (a mesh file instead of `tetloc gen`).
set -uo pipefail
wheel=${1:?usage: OUT=DIR scripts/h200/torch.sh WHEEL TETLOC_BIN}
bin=${2:?usage: OUT=DIR scripts/h200/torch.sh WHEEL TETLOC_BIN}
. "$(dirname "$0")/common.sh" # wheel_setup, step
wheel_setup torch "$wheel"

device=${TORCH_DEVICE:-cuda}
"$py" - <<'PY' 2>&1 | tee "$out/versions.txt"
import sys, numpy, torch, tetloc
print("python", sys.version.split()[0], "numpy", numpy.__version__, "torch", torch.__version__,
      "cuda", torch.version.cuda, "available", torch.cuda.is_available())
print("tetloc", tetloc.__version__, "Vulkan devices", [(d["name"], d["driver"]) for d in tetloc.devices()])
PY

step cuda_checks 150 "$py" "$repo/python/tests/cuda_torch.py" "${data[@]}" --device "$device" \
  --json "$out/cuda_checks.json"

mesh=${MESH:-$work/jets12M.vtu}
[ -f "$mesh" ] || step gen_jets12M 90 "$bin" gen jets --cells 12M -o "$mesh"
if [ -f "$mesh" ]; then
  bench=("$py" "$repo/python/benchmarks/bench_torch.py" "$mesh" --device "$device" --repeats 3)
  step bench_torch 250 "${bench[@]}" --points "${POINTS:-16M}" --json "$out/bench_torch.json"
  # Too little memory or time for 16M points: the same at 4M, so that some figure comes back,
  # in what is left of 9 minutes.
  left=$((560 - SECONDS))
  if [ ! -f "$out/bench_torch.json" ] && [ "$left" -gt 60 ]; then
    step bench_torch_4M "$left" "${bench[@]}" --points 4M --json "$out/bench_torch_4M.json"
  fi
fi
echo "== done $(date -u +%H:%M:%S): $failed failed step(s)"
exit "$failed"

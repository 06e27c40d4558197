#!/usr/bin/env bash
# Runs every check of the workspace: the formatting gate (`cargo fmt --check`), then it
# installs what the tests need (the Vulkan loader and lavapipe, Mesa's CPU Vulkan driver with
# ray-tracing pipelines, from bookworm-backports, the validation layers, and OpenMPI), and
# builds and runs the tests. The GPU tests run on whatever Vulkan device there is; with CI set,
# a test that finds no device or no oracle data fails instead of skipping. Arguments go to the
# workspace's `cargo test`.
#
# One build serves the lints and the tests: clippy runs as the compiler of the workspace's own
# crates (RUSTC_WORKSPACE_WRAPPER, what `cargo clippy` does for `cargo check`) while
# `cargo test` builds them, so nothing is compiled twice for `clippy -D warnings`. The fuzz
# crate is a workspace member, and the feature `mpi` of tetloc-mpi is on in that build, so
# the MPI step rebuilds only the CLI.
#
# The run ends with a table of the steps' times and one line that counts the checks that did
# not run (each skip is listed in target/skipped.txt as `test<TAB>reason`).
set -euo pipefail
cd "$(dirname "$0")/.."

# The tests append every skip here (tetloc_testdata::skip, python/tests/conftest.py).
mkdir -p target
export TETLOC_SKIP_LOG="$PWD/target/skipped.txt"
: >"$TETLOC_SKIP_LOG"

# step NAME COMMAND...: runs COMMAND and records how long it took, for the table at the end;
# returns COMMAND's status (set -e then ends the run, except in a gate, which says why).
steps=()
step() {
  local name=$1 start=$SECONDS rc=0
  shift
  echo "test.sh: $name"
  "$@" || rc=$?
  local took=$((SECONDS - start))
  steps+=("$(printf '%-34s %4dm%02ds%s' "$name" $((took / 60)) $((took % 60)) "$([ $rc = 0 ] || echo '  FAILED')")")
  return $rc
}
# gate NAME FIX COMMAND...: a step that, on failure, says which gate failed and how to fix it.
gate() {
  local name=$1 fix=$2
  shift 2
  if ! step "$name" "$@"; then
    echo "test.sh: FAILED gate '$name'; $fix" >&2
    exit 1
  fi
}
# The summary: the steps' times, then how many checks did not run, by reason.
summary() {
  echo "test.sh: step times"
  printf '  %s\n' "${steps[@]}"
  printf '  %-34s %4dm%02ds\n' "total" $((SECONDS / 60)) $((SECONDS % 60))
  awk -F'\t' '{ n[$2]++; total++ }
    END {
      if (!total) { print "not run: 0 checks"; exit }
      line = sprintf("not run: %d check%s (", total, total == 1 ? "" : "s")
      sep = ""
      for (r in n) { line = line sep n[r] ": " r; sep = "; " }
      print line "); see target/skipped.txt"
    }' "$TETLOC_SKIP_LOG"
}
trap summary EXIT

gate "format" "run 'cargo fmt --all' to fix it" cargo fmt --all --check

step "install test dependencies" bash scripts/install-test-deps.sh
# Prefer lavapipe when no other driver is set, so results do not depend on a desktop GPU.
if [ -z "${VK_DRIVER_FILES:-}${VK_ICD_FILENAMES:-}" ] && [ -n "${CI:-}" ]; then
  lvp=$(ls /usr/share/vulkan/icd.d/lvp_icd*.json 2>/dev/null | head -n1 || true)
  [ -n "$lvp" ] && export VK_DRIVER_FILES="$lvp"
fi
export LP_NUM_THREADS="${LP_NUM_THREADS:-$(nproc)}"

# --- Python (python/): a virtualenv under target/ with what the Python tests need, from the
# package index by name (kept between runs). TETLOC_PYTHON is that interpreter, for Rust tests
# that call VTK through Python.
venv=target/pyenv
python_env() {
  { [ -x "$venv/bin/python" ] || python3 -m venv "$venv"; } &&
    # (netCDF4: python/tests/test_exodus.py writes Exodus II files with it, as SEACAS lays them out.)
    "$venv/bin/python" -m pip install -q --disable-pip-version-check numpy pytest maturin pyvista meshio vtk scipy mypy websocket-client netCDF4 &&
    # tetloc.torch's tests (python/tests/test_torch.py). The default index's Linux wheel brings
    # the CUDA libraries: on a fresh venv (2026-12-05, torch 2.15.0) 2 min 11 s and 5.2 GB
    # (torch 1.2, nvidia-* 3.0, triton 1.0); kept with the venv between runs.
    "$venv/bin/python" -m pip install -q --disable-pip-version-check torch
}
step "python virtualenv" python_env
export TETLOC_PYTHON="$PWD/$venv/bin/python"
# --- end of the Python setup

# Clippy, with warnings denied, compiles the workspace's crates in every cargo and maturin
# build below (CLIPPY_ARGS is how `cargo clippy` passes `-D warnings` to clippy-driver).
export RUSTC_WORKSPACE_WRAPPER="$(rustc --print sysroot)/bin/clippy-driver"
export CLIPPY_ARGS="-D__CLIPPY_HACKERY__warnings__CLIPPY_HACKERY__"
# tetloc-mpi's MPI code is built (and linted, and its unit tests run) with the workspace; the
# CLI's feature `mpi` changes its binary, so it is built apart, for the MPI test only.
features=(--features tetloc-mpi/mpi)
gate "clippy + test build" "see the messages above" cargo test --workspace --locked "${features[@]}" --no-run "$@"
step "cargo test" cargo test --workspace --locked "${features[@]}" "$@"
# The API docs build without a warning (broken or private intra-doc links, bad code blocks):
# rustdoc over the workspace's crates, the dependencies only checked. Without clippy as the
# compiler (the build above linted the crates) and without the feature `mpi` (its bindings
# would be generated again for this build).
gate "cargo doc" "fix the rustdoc warnings named above" \
  env -u RUSTC_WORKSPACE_WRAPPER RUSTDOCFLAGS="-D warnings" cargo doc --workspace --no-deps --locked

# --- MPI: `mpirun -n 1, 2, 4` of the binary built with the feature `mpi` over partitioned
# oracle sets (crates/tetloc-cli/tests/mpi.rs); with the same features as above plus the CLI's,
# so only the CLI is rebuilt (and its MPI code linted).
gate "MPI: clippy + build" "see the messages above" \
  cargo test --workspace --locked --features tetloc-mpi/mpi,tetloc-cli/mpi --test mpi --no-run
step "MPI: test" cargo test --workspace --locked --features tetloc-mpi/mpi,tetloc-cli/mpi --test mpi

# --- Python: build the wheel once (clippy lints the Python crate here), install it into the
# virtualenv, and run pytest; the CLI tests compare with the binary `cargo test` built. A dev
# build: the dev profile is the tests' (optimised, Cargo.toml), so it reuses their build where
# the Python crate's features allow; `pip install ./python` builds the release wheel.
wheel() {
  # (`&&`: a gate's commands run without set -e.)
  rm -f target/wheels/tetloc-*.whl &&
    "$venv/bin/maturin" build --quiet --manifest-path python/Cargo.toml --interpreter "$TETLOC_PYTHON" \
      --out target/wheels &&
    "$venv/bin/python" -m pip install -q --disable-pip-version-check --force-reinstall --no-deps target/wheels/tetloc-*.whl
}
gate "Python: clippy + wheel" "see the messages above" wheel
# The type gate: mypy over the package (strict) and the tests, examples and benchmarks that use
# it (python/pyproject.toml), and stubtest, which holds the extension's stub
# (tetloc/_tetloc.pyi) to the installed wheel's functions and classes; then the wheel's
# `py.typed`. From the repository root, so that `tetloc` is the installed package.
types() {
  (cd python && "../$venv/bin/mypy") &&
    "$venv/bin/python" -m mypy.stubtest --concise tetloc._tetloc &&
    "$venv/bin/python" -c 'import pathlib, tetloc; assert (pathlib.Path(tetloc.__file__).parent / "py.typed").is_file(), "the wheel has no py.typed"'
}
gate "Python: types (mypy, stubtest)" "fix the annotations or tetloc/_tetloc.pyi named above" types
# The binary `cargo test` built, wherever cargo puts its builds (CARGO_TARGET_DIR).
cargo_target=$(cargo metadata --format-version 1 --no-deps | "$venv/bin/python" -c 'import json, sys; print(json.load(sys.stdin)["target_directory"])')
step "Python: pytest" env TETLOC_CLI="$cargo_target/debug/tetloc" "$venv/bin/python" -m pytest -q python/tests

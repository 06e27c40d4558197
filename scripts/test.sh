#!/usr/bin/env bash
# Runs every check of the workspace. First the gates, which fail fast with the command that
# fixes or shows the problem: formatting (`cargo fmt --check`) and lints (`cargo clippy
# -D warnings`), each for the workspace and the fuzz crate. Then it installs what the tests
# need (the Vulkan loader and lavapipe, Mesa's CPU Vulkan driver with ray-tracing pipelines,
# from bookworm-backports, and the validation layers) and runs `cargo test`. The GPU tests
# run on whatever Vulkan device there is; with CI set, a test that finds no device or no
# oracle data fails instead of skipping. Arguments go to the workspace's `cargo test`. The MPI
# tests (OpenMPI installed with the rest) run last, with the feature `mpi` on.
set -euo pipefail
cd "$(dirname "$0")/.."

# gate NAME FIX COMMAND...: runs COMMAND; on failure says which gate failed and how to fix it.
gate() {
  local name=$1 fix=$2
  shift 2
  echo "test.sh: gate: $name"
  if ! "$@"; then
    echo "test.sh: FAILED gate '$name'; $fix" >&2
    exit 1
  fi
}
# The fuzz crate is its own workspace (cargo-fuzz builds it with nightly), so each gate runs twice.
gate "format" "run 'cargo fmt --all' to fix it" cargo fmt --all --check
gate "format (fuzz)" "run 'cargo fmt --all --manifest-path fuzz/Cargo.toml' to fix it" \
  cargo fmt --all --check --manifest-path fuzz/Cargo.toml
gate "clippy" "see the messages above" cargo clippy --workspace --all-targets --locked -- -D warnings
gate "clippy (fuzz)" "see the messages above" \
  cargo clippy --manifest-path fuzz/Cargo.toml --lib --tests --locked -- -D warnings

bash scripts/install-test-deps.sh
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
[ -x "$venv/bin/python" ] || python3 -m venv "$venv"
"$venv/bin/python" -m pip install -q --disable-pip-version-check numpy pytest maturin pyvista meshio vtk scipy
export TETLOC_PYTHON="$PWD/$venv/bin/python"
# --- end of the Python setup
# The fuzz targets' bodies over the shared data, truncations and byte flips (stable toolchain;
# the fuzz crate is its own workspace so that cargo-fuzz can build it with nightly).
cargo test --locked --manifest-path fuzz/Cargo.toml --lib
cargo test --workspace --locked "$@"

# --- MPI (feature `mpi`, off by default): lints with the feature, then `mpirun -n 1, 2, 4` of
# the binary built with it over partitioned oracle sets (crates/tetloc-cli/tests/mpi.rs).
gate "clippy (mpi)" "see the messages above" \
  cargo clippy -p tetloc-mpi -p tetloc-cli --features mpi --all-targets --locked -- -D warnings
cargo test -p tetloc-mpi --features mpi --locked
cargo test -p tetloc-cli --features mpi --locked --test mpi

# --- Python: build the release wheel once (what `pip install ./python` builds), install it
# into the virtualenv, and run pytest; the CLI tests compare with the binary `cargo test` built.
rm -f target/wheels/tetloc-*.whl
"$venv/bin/maturin" build --quiet --release --manifest-path python/Cargo.toml --interpreter "$TETLOC_PYTHON" \
  --out target/wheels
"$venv/bin/python" -m pip install -q --disable-pip-version-check --force-reinstall --no-deps target/wheels/tetloc-*.whl
# The binary `cargo test` built, wherever cargo puts its builds (CARGO_TARGET_DIR).
cargo_target=$(cargo metadata --format-version 1 --no-deps | "$venv/bin/python" -c 'import json, sys; print(json.load(sys.stdin)["target_directory"])')
TETLOC_CLI="$cargo_target/debug/tetloc" "$venv/bin/python" -m pytest -q python/tests

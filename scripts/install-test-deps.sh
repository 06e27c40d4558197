#!/usr/bin/env bash
# Installs what the tests need on Debian: lavapipe (Mesa's CPU Vulkan driver, with
# ray-tracing pipelines since Mesa 25) and the Vulkan loader from bookworm-backports,
# plus the validation layers (the GPU tests run with them on, and the smoke test checks
# that they are), and OpenMPI with its headers and libclang (the MPI tests: rsmpi binds the
# system's MPI through bindgen). Each part is checked on its own, so a machine that already
# has lavapipe still gets the layers. The backports source reuses the URIs of the machine's own Debian
# sources, so no registry host is named here.
set -euo pipefail
[ "$(id -u)" = 0 ] && SUDO= || SUDO=sudo

# grep reads the whole list (no -q): with pipefail, an early exit would kill ldconfig with
# SIGPIPE and fail the check when the library is there (seen on a fresh machine, 2026-12-05).
have_driver() {
  ldconfig -p | grep libvulkan.so.1 >/dev/null && ls /usr/share/vulkan/icd.d/lvp_icd*.json >/dev/null 2>&1
}
have_layers() {
  ls /usr/share/vulkan/explicit_layer.d/VkLayer_khronos_validation.json >/dev/null 2>&1
}

have_mpi() {
  command -v mpirun >/dev/null 2>&1 && command -v mpicc >/dev/null 2>&1 && ldconfig -p | grep libclang >/dev/null
}
# The viewer's browser tests (python/tests/test_view.py) drive headless Chromium.
have_chromium() {
  command -v chromium >/dev/null 2>&1
}

need_driver=1
need_layers=1
need_mpi=1
need_chromium=1
if [ -z "${TETLOC_REINSTALL_DEPS:-}" ]; then
  have_driver && need_driver=
  have_layers && need_layers=
  have_mpi && need_mpi=
  have_chromium && need_chromium=
fi
if [ -z "$need_driver$need_layers$need_mpi$need_chromium" ]; then
  echo "install-test-deps: Vulkan loader, lavapipe, validation layers, OpenMPI and Chromium already present"
  exit 0
fi

src=/etc/apt/sources.list.d/debian.sources
uris=$(awk '/^URIs:/ {print $2; exit}' "$src" 2>/dev/null || true)
if [ -z "$uris" ]; then
  uris=$(awk '/^deb / && $3 ~ /^bookworm$/ {print $2; exit}' /etc/apt/sources.list 2>/dev/null || true)
fi
if [ -z "$uris" ]; then
  echo "install-test-deps: cannot find the Debian mirror in $src or /etc/apt/sources.list" >&2
  exit 1
fi
bp=/etc/apt/sources.list.d/tetloc-backports.sources
if [ ! -f "$bp" ]; then
  printf 'Types: deb\nURIs: %s\nSuites: bookworm-backports\nComponents: main\nSigned-By: /usr/share/keyrings/debian-archive-keyring.gpg\n' "$uris" | $SUDO tee "$bp" >/dev/null
fi
export DEBIAN_FRONTEND=noninteractive
$SUDO apt-get update -qq
if [ -n "$need_driver" ]; then
  echo "install-test-deps: installing the Vulkan loader and lavapipe"
  $SUDO apt-get install -y -qq -t bookworm-backports mesa-vulkan-drivers libvulkan1 >/dev/null
fi
if [ -n "$need_layers" ]; then
  # From backports when it has them (to match the loader), else from the release.
  echo "install-test-deps: installing the Vulkan validation layers"
  $SUDO apt-get install -y -qq -t bookworm-backports vulkan-validationlayers >/dev/null 2>&1 \
    || $SUDO apt-get install -y -qq vulkan-validationlayers >/dev/null
fi
if [ -n "$need_mpi" ]; then
  echo "install-test-deps: installing OpenMPI and libclang"
  $SUDO apt-get install -y -qq openmpi-bin libopenmpi-dev libclang-dev >/dev/null
fi
if [ -n "$need_chromium" ]; then
  echo "install-test-deps: installing Chromium"
  $SUDO apt-get install -y -qq chromium >/dev/null
fi
if ! have_driver || ! have_layers || ! have_mpi || ! have_chromium; then
  echo "install-test-deps: lavapipe, the validation layers, OpenMPI or Chromium are still missing after the install" >&2
  exit 1
fi
echo "install-test-deps: done"

#!/usr/bin/env bash
# Installs what the tests need on Debian: lavapipe (Mesa's CPU Vulkan driver, with
# ray-tracing pipelines since Mesa 25) and the Vulkan loader from bookworm-backports,
# plus the validation layers. The backports source reuses the URIs of the machine's
# own Debian sources, so no registry host is named here.
set -euo pipefail
[ "$(id -u)" = 0 ] && SUDO= || SUDO=sudo
if ldconfig -p | grep -q libvulkan.so.1 && ls /usr/share/vulkan/icd.d/lvp_icd*.json >/dev/null 2>&1 \
   && [ -z "${TETLOC_REINSTALL_DEPS:-}" ]; then
  echo "install-test-deps: Vulkan loader and lavapipe already present"
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
$SUDO apt-get install -y -qq -t bookworm-backports mesa-vulkan-drivers libvulkan1 >/dev/null
# Validation layers (optional: tests turn them on when present).
$SUDO apt-get install -y -qq -t bookworm-backports vulkan-validationlayers >/dev/null 2>&1 \
  || $SUDO apt-get install -y -qq vulkan-validationlayers >/dev/null 2>&1 || true
echo "install-test-deps: done"

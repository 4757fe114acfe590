#!/usr/bin/env bash
# The test command (README "The two commands"; .ci/run calls exactly this): makes sure a
# Vulkan driver is there for the GPU tests — installing Mesa's lavapipe (software Vulkan)
# when none is — then runs the whole suite, GPU tests included, in release mode.
set -euo pipefail
cd "$(dirname "$0")/.."

have_vulkan() {
  ls /usr/share/vulkan/icd.d/*.json >/dev/null 2>&1 && ldconfig -p | grep libvulkan.so.1 >/dev/null
}

if ! have_vulkan; then
  echo "no Vulkan driver found: installing lavapipe (mesa-vulkan-drivers libvulkan1)"
  SUDO=""
  if [ "$(id -u)" -ne 0 ]; then
    if command -v sudo >/dev/null 2>&1; then SUDO="sudo"; fi
  fi
  if command -v apt-get >/dev/null 2>&1 && { [ "$(id -u)" -eq 0 ] || [ -n "$SUDO" ]; }; then
    export DEBIAN_FRONTEND=noninteractive
    $SUDO apt-get update -qq
    $SUDO apt-get install -y -qq mesa-vulkan-drivers libvulkan1 >/dev/null
  fi
  if ! have_vulkan; then
    cat >&2 <<'MSG'
error: the GPU tests need a Vulkan driver and none could be installed here.
  Debian/Ubuntu:  sudo apt-get install mesa-vulkan-drivers libvulkan1   (lavapipe, software)
  Fedora:         sudo dnf install mesa-vulkan-drivers vulkan-loader
  Arch:           sudo pacman -S vulkan-swrast vulkan-icd-loader
  or install your GPU vendor's Vulkan driver, then run this script again.
MSG
    exit 1
  fi
fi

cargo test --release "$@"

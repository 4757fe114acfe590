#!/usr/bin/env bash
# The test command (README "The two commands"; .ci/run calls exactly this): makes sure a
# Vulkan driver is there for the GPU tests — installing Mesa's lavapipe (software Vulkan)
# when none is — then runs the whole suite, GPU tests included, in release mode, and builds
# the book (scripts/book.sh).
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

# The book (docs/): built with mdBook, failing on a broken internal link.
scripts/book.sh

# The API docs: every intra-doc link resolves (rustdoc's warnings are errors).
RUSTDOCFLAGS="-D warnings" cargo doc --release --no-deps --quiet

# The examples a newcomer runs first (docs/src/library.md): each prints a few lines and
# checks its own results (CPU and GPU hits bit for bit); seconds each on the CPU or lavapipe.
for example in trace_arrays render_scene custom_layout; do
  echo "example $example"
  cargo run --release --example "$example"
done

# The driver's own traversal (tests/driver.rs) needs an adapter with ray queries. Debian 12's
# lavapipe (Mesa 22.3) has none; Mesa 25's, in the bookworm-backports suite, has. Where apt can
# reach that suite, its lavapipe is unpacked beside the system's (target/mesa25; the system
# driver stays what it is) and tests/driver.rs runs again on it, where a missing feature fails.
# Whether apt offers mesa-vulkan-drivers from bookworm-backports (no pipe into grep -q: under
# pipefail its early exit would fail the pipeline).
has_backports() {
  local policy
  policy=$(apt-cache policy mesa-vulkan-drivers 2>/dev/null) || return 1
  [[ $policy == *bookworm-backports* ]]
}

ray_query_lavapipe() {
  local dir=target/mesa25 lib=usr/lib/x86_64-linux-gnu
  if [ -f "$dir/lvp_icd.json" ]; then return 0; fi
  [ "$(uname -m)" = x86_64 ] || return 1
  grep -q '^VERSION_CODENAME=bookworm' /etc/os-release 2>/dev/null || return 1
  command -v apt-get >/dev/null 2>&1 || return 1
  local SUDO=""
  if [ "$(id -u)" -ne 0 ]; then
    command -v sudo >/dev/null 2>&1 || return 1
    SUDO="sudo"
  fi
  local src=/etc/apt/sources.list.d/debian.sources
  if ! has_backports; then
    # Enable the suite on the machine's own apt source (its Suites line), never a new address.
    [ -f "$src" ] || return 1
    if ! grep -q '^Suites:.*bookworm-backports' "$src"; then
      grep -q '^Suites: bookworm bookworm-updates$' "$src" || return 1
      $SUDO sed -i 's/^Suites: bookworm bookworm-updates$/& bookworm-backports/' "$src"
    fi
    $SUDO apt-get update -qq || return 1
    has_backports || return 1
  fi
  rm -rf "$dir.tmp" && mkdir -p "$dir.tmp/debs"
  (cd "$dir.tmp/debs" && apt-get download -qq mesa-vulkan-drivers/bookworm-backports \
      libdrm2/bookworm-backports libdrm-amdgpu1/bookworm-backports 2>/dev/null) || return 1
  for deb in "$dir.tmp"/debs/*.deb; do dpkg-deb -x "$deb" "$dir.tmp/root"; done
  local so="$PWD/$dir/root/$lib/libvulkan_lvp.so"
  sed "s#\"library_path\": \"[^\"]*\"#\"library_path\": \"$so\"#" \
    "$dir.tmp/root/usr/share/vulkan/icd.d/lvp_icd.json" > "$dir.tmp/lvp_icd.json"
  rm -rf "$dir" && mv "$dir.tmp" "$dir"
}

if ray_query_lavapipe; then
  echo "tests/driver.rs again on Mesa 25 lavapipe (ray queries), unpacked in target/mesa25"
  VK_ICD_FILENAMES="$PWD/target/mesa25/lvp_icd.json" \
    LD_LIBRARY_PATH="$PWD/target/mesa25/root/usr/lib/x86_64-linux-gnu${LD_LIBRARY_PATH:+:$LD_LIBRARY_PATH}" \
    LANCER_EXPECT_RAY_QUERY=1 cargo test --release --test driver
else
  echo "note: tests/driver.rs met no adapter with ray queries, so the driver's traversal was" \
    "not tested here (on Debian 12 this script unpacks Mesa 25 lavapipe from bookworm-backports)" >&2
fi

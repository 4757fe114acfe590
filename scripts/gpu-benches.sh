#!/usr/bin/env bash
# The checks and benches to run on a machine with a hardware GPU and no Rust toolchain (a
# lent or rented GPU box), in one go, from a kit of prebuilt programs. Two steps:
#
#   scripts/gpu-benches.sh pack KIT          # here: build lancer at a clean commit, gather the kit
#   scripts/gpu-benches.sh run KIT OUT [S]   # there, in a copy of this repository: check, bench,
#                                            # and leave OUT/results.tar.gz and OUT/log.txt
#
# KIT can be `.gpu-kit` (ignored by git), to travel with a copy of the repository.
#
# `run` takes at most S seconds in all (default 480), each step under its own limit, the
# most important first: `lancer check` (every layout's GPU kernel against its CPU twin, on
# the bunny and a 1M-triangle terrain), then `bench scale` (from the file to the first rays,
# step by step), `bench instances` (two levels against the flattened copy), `bench layouts`,
# `bench render` and `bench builders`.
# A step that fails or runs out of time is logged and the next one runs. The results pages
# are written where the book keeps them (docs/src/results/DATE-*-gpu*.md, with their charts)
# and packed into OUT/results.tar.gz; unpack that in the repository root and commit the
# pages (docs/src/results/index.md says how they are linked). See docs/src/benchmarks.md.
set -uo pipefail
cd "$(dirname "$0")/.."

usage() {
  echo "usage: $0 pack KIT | $0 run KIT OUT [SECONDS]" >&2
  exit 2
}

pack() {
  local kit=$1
  if [ -n "$(git status --porcelain --untracked-files=no)" ]; then
    echo "error: tracked files have uncommitted changes: commit first, so that the pages name the commit measured" >&2
    exit 2
  fi
  set -e
  mkdir -p "$kit/models" "$kit/gl"
  # Default features: no Embree (the GPU machine may not have its library).
  cargo build --release --bin lancer --example terrain
  strip -o "$kit/lancer" target/release/lancer
  strip -o "$kit/terrain" target/release/examples/terrain
  cp ../shared/models/*.obj "$kit/models/"
  # The Vulkan loader, for a machine that has the driver but not the loader
  # (unpacked there only where `ldconfig` finds no libvulkan.so.1).
  if command -v apt-get >/dev/null 2>&1; then
    local lists
    lists=$(mktemp -d)
    local o=(-oAPT::Architecture=amd64 -oAPT::Architectures=amd64 "-oDir::State::Lists=$lists")
    mkdir -p "$lists/partial"
    apt-get "${o[@]}" update -qq >/dev/null 2>&1 &&
      (cd "$kit/gl" && apt-get "${o[@]}" download libvulkan1 >/dev/null 2>&1) ||
      echo "note: no Vulkan loader package fetched (the GPU machine must have libvulkan.so.1)"
    rm -rf "$lists"
  fi
  echo "kit in $kit: $(du -sh "$kit" | cut -f1) (lancer $(git rev-parse --short HEAD))"
}

run() {
  local kit out budget
  kit=$(cd "$1" 2>/dev/null && pwd) || {
    echo "error: no kit at $1 (make one with: $0 pack KIT)" >&2
    exit 2
  }
  out=$2
  budget=${3:-480}
  mkdir -p "$out"
  out=$(cd "$out" && pwd)
  local log=$out/log.txt
  local end=$((SECONDS + budget))
  local day
  day=$(date -u +%F)
  : >"$log"
  # What the benches write is newer than this (pages of the same day already there are not).
  local since=$out/.since
  touch "$since"
  sleep 1
  say() { echo "$*" | tee -a "$log"; }

  # The loader, where the machine lacks it; NVIDIA's driver file where no other is listed.
  # (grep reads to the end: with pipefail, an early exit could fail ldconfig on SIGPIPE.)
  if ! ldconfig -p | grep libvulkan.so.1 >/dev/null; then
    for f in "$kit"/gl/*.deb; do [ -e "$f" ] && dpkg -x "$f" /; done
    ldconfig
  fi
  local icd=/usr/local/nvidia/share/vulkan/icd.d/nvidia_icd.json
  if [ -e "$icd" ] && ! ls /usr/share/vulkan/icd.d/*.json /etc/vulkan/icd.d/*.json >/dev/null 2>&1; then
    # The first for current loaders, the second for older ones.
    export VK_DRIVER_FILES=$icd VK_ICD_FILENAMES=$icd
  fi
  export PATH=$kit:$PATH
  mkdir -p /tmp/meshes
  local bunny=$kit/models/stanford-bunny.obj

  # step LIMIT NAME COMMAND...: runs COMMAND under min(LIMIT, what is left), logged.
  step() {
    local limit=$1 name=$2
    shift 2
    local left=$((end - SECONDS))
    if [ "$left" -lt 10 ]; then
      say "== $name: skipped (no time left)"
      return
    fi
    [ "$limit" -gt "$left" ] && limit=$left
    say "== $name ($*), at most ${limit} s"
    local t0=$SECONDS
    timeout --signal=INT --kill-after=10 "$limit" "$@" >>"$log" 2>&1
    local rc=$?
    say "== $name: exit $rc after $((SECONDS - t0)) s"
  }

  step 30 adapters lancer adapters
  step 60 meshes terrain 1000000 /tmp/meshes/terrain-1M.ply
  step 60 meshes terrain 4000000 /tmp/meshes/terrain-4M.ply
  step 60 check-bunny lancer check "$bunny" --device gpu
  step 90 check-terrain lancer check /tmp/meshes/terrain-1M.ply --device gpu
  step 90 scale lancer bench scale /tmp/meshes/terrain-1M.ply /tmp/meshes/terrain-4M.ply \
    --layout dfs-sign --device gpu --repeat 3 --report "docs/src/results/$day-scale-gpu.md"
  step 90 instances lancer bench instances "$bunny" --copies 16 --device gpu --repeat 3 \
    --report "docs/src/results/$day-instances-gpu.md"
  step 120 layouts lancer bench layouts "$bunny" --device gpu --width 256 --height 256 --repeat 3 \
    --report "docs/src/results/$day-layouts-gpu.md"
  step 90 render lancer bench render scenes/cornell.toml --device gpu \
    --report "docs/src/results/$day-render-gpu.md"
  step 150 builders lancer bench builders /tmp/meshes/terrain-1M.ply "$bunny" --builder binned \
    --builder ploc --builder lbvh --device gpu --repeat 3 --width 256 --height 256 \
    --report "docs/src/results/$day-builders-gpu.md"

  # Everything the benches wrote under docs/src/results (pages and charts) in one file.
  local pages
  pages=$(find docs/src/results -maxdepth 1 -name "$day-*-gpu*" -newer "$since" | sort)
  rm -f "$since"
  if [ -n "$pages" ]; then
    # shellcheck disable=SC2086 # one name a line, no spaces in them
    tar czf "$out/results.tar.gz" $pages
    say "results: $(echo "$pages" | wc -l) files in $out/results.tar.gz"
  else
    say "results: none written"
  fi
}

case "${1:-}" in
  pack) [ $# -eq 2 ] || usage; pack "$2" ;;
  run) [ $# -ge 3 ] && [ $# -le 4 ] || usage; run "$2" "$3" "${4:-480}" ;;
  *) usage ;;
esac

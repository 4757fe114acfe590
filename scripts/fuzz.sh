#!/usr/bin/env bash
# Coverage-guided fuzzing of every reader (cargo-fuzz: libFuzzer with AddressSanitizer, on
# the nightly toolchain). Usage: scripts/fuzz.sh [SECONDS per target, default 60] [TARGET…]
#
# Each target (fuzz/fuzz_targets: obj, mtl, ply, gltf, glb, scene, exr, bvh, rays, hits)
# starts from a seed corpus of the repository's own files (written by the ignored test
# write_fuzz_seeds in tests/fuzz_readers.rs) and runs for the given time. Every crash, abort,
# leak-free hang (-timeout) or out-of-memory it finds is copied to tests/fuzz-regressions/
# TARGET/, where `cargo test --test fuzz_readers` runs it from then on. The last line per
# target says how many executions it ran and what it found.
set -euo pipefail
cd "$(dirname "$0")/.."
secs=${1:-60}
shift || true
targets=("$@")
if [ ${#targets[@]} -eq 0 ]; then
  targets=(obj mtl ply gltf glb scene exr bvh rays hits)
fi
command -v cargo-fuzz >/dev/null || cargo install cargo-fuzz --locked

corpus=fuzz/corpus
LANCER_FUZZ_SEEDS="$PWD/$corpus" cargo test --release --test fuzz_readers write_fuzz_seeds \
  -- --ignored --quiet >/dev/null
cargo +nightly fuzz build --fuzz-dir fuzz

summary=()
for t in "${targets[@]}"; do
  mkdir -p "$corpus/$t" "fuzz/artifacts/$t"
  log="fuzz/artifacts/$t.log"
  # -timeout: one input over 20 s is a hang; -rss_limit_mb: a reader growing past 4 GiB.
  cargo +nightly fuzz run --fuzz-dir fuzz "$t" "$corpus/$t" -- \
    -max_total_time="$secs" -timeout=20 -rss_limit_mb=4096 -print_final_stats=1 \
    >"$log" 2>&1 || true
  runs=$(grep -o 'stat::number_of_executed_units: *[0-9]*' "$log" | grep -o '[0-9]*$' || echo "?")
  found=0
  for f in fuzz/artifacts/"$t"/{crash,oom,timeout,leak}-*; do
    [ -e "$f" ] || continue
    mkdir -p "tests/fuzz-regressions/$t"
    cp "$f" "tests/fuzz-regressions/$t/"
    found=$((found + 1))
  done
  summary+=("$t: $runs executions in ${secs} s, $found findings")
  echo "${summary[-1]}"
done
printf '%s\n' "${summary[@]}" >fuzz/artifacts/summary.txt
echo "summary: fuzz/artifacts/summary.txt; findings (if any) copied to tests/fuzz-regressions/"

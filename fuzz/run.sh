#!/usr/bin/env bash
# Coverage-guided fuzzing on the stable toolchain, without cargo-fuzz or nightly.
#
#   fuzz/run.sh TARGET [SECONDS] [libFuzzer options...]
#
# cargo-fuzz asks for nightly only for its sanitizer flags (-Zsanitizer). libFuzzer's coverage
# feedback needs none of them: SanitizerCoverage is an LLVM pass that stable rustc runs through
# -Cpasses and -Cllvm-args (the same flags cargo-fuzz passes). `--target` keeps RUSTFLAGS off
# build scripts and proc macros, which must not be instrumented (they are linked without
# libFuzzer). Debug assertions and overflow checks are on, as under cargo-fuzz.
#
# Without these flags a libFuzzer binary has no coverage and its corpus never grows beyond the
# seeds (the fuzz targets' earlier runs here showed exactly that).
set -euo pipefail
cd "$(dirname "$0")"
target="${1:?usage: fuzz/run.sh TARGET [SECONDS] [libFuzzer options...]}"
seconds="${2:-600}"
shift $(($# < 2 ? $# : 2))
triple="$(rustc -vV | sed -n 's/^host: //p')"
# Seeds first: seed.sh runs the main crate's tests (a plain build), which must not see the
# instrumentation flags below (its build scripts would not link without libFuzzer).
[ -d "corpus/$target" ] || ./seed.sh
export CARGO_TARGET_DIR="${CARGO_TARGET_DIR:-target}"
export RUSTFLAGS="-Cpasses=sancov-module \
  -Cllvm-args=-sanitizer-coverage-level=4 \
  -Cllvm-args=-sanitizer-coverage-inline-8bit-counters \
  -Cllvm-args=-sanitizer-coverage-pc-table \
  -Cllvm-args=-sanitizer-coverage-trace-compares \
  --cfg fuzzing -Cdebug-assertions -Coverflow-checks"
cargo build --locked --release --target "$triple" --bin "$target"
mkdir -p "artifacts/$target" "corpus/$target.new"
# New inputs go to corpus/TARGET.new; the seeds stay as seed.sh made them.
exec "$CARGO_TARGET_DIR/$triple/release/$target" \
  -max_total_time="$seconds" -rss_limit_mb=4096 -timeout=20 -max_len=1048576 \
  -artifact_prefix="artifacts/$target/" "$@" "corpus/$target.new" "corpus/$target"

#!/usr/bin/env bash
# The README's test command: every Rust test (`cargo test --locked`), then the Python
# package's build and pytest suite (scripts/test-python.sh). Arguments go to cargo test.
set -euo pipefail
cd "$(dirname "$0")/.."
cargo test --locked "$@"
scripts/test-python.sh

#!/usr/bin/env bash
# Builds the Python package (python/) with `pip install ./python` into a virtual environment
# and runs its pytest suite (python/tests) against the meshtracer binary.
#
# The wheel is built with python/Cargo.toml's `quick` profile (opt-level 1, no debug info:
# that file says why) into the target folder of `cargo test`; set
# MESHTRACER_PYTHON_PROFILE=release for the optimised build a user gets from
# `pip install ./python`.
#
# Anything missing (python3's venv module, PyPI) fails the run with a message: this script
# never skips the Python tests silently.
set -euo pipefail
cd "$(dirname "$0")/.."
root="$PWD"
target="${CARGO_TARGET_DIR:-$root/target}"
venv="${MESHTRACER_VENV:-$target/python-venv}"
profile="${MESHTRACER_PYTHON_PROFILE:-quick}"

if [ ! -x "$venv/bin/python" ]; then
  if ! python3 -m venv "$venv"; then
    echo "error: 'python3 -m venv $venv' failed: the Python tests need python3 with its venv module (Debian: apt-get install python3-venv)" >&2
    exit 1
  fi
fi
"$venv/bin/python" -m pip install --quiet --disable-pip-version-check -r python/requirements-test.txt

# The binary the tests compare against, target/debug/meshtracer, as `cargo test` builds it
# (with the dev-dependencies' features: `cargo build` would compile much of the tree again).
# After cargo test, as in scripts/test.sh, this does nothing.
if [ -z "${MESHTRACER_CLI:-}" ]; then
  cargo test --locked --no-run --quiet
fi

start=$(date +%s)
CARGO_TARGET_DIR="$target" MATURIN_PEP517_ARGS="--profile $profile" \
  "$venv/bin/python" -m pip install --quiet --disable-pip-version-check --force-reinstall --no-deps ./python
echo "python package built and installed ($profile profile) in $(( $(date +%s) - start )) s"

cd python/tests
MESHTRACER_CLI="${MESHTRACER_CLI:-$target/debug/meshtracer}" "$venv/bin/python" -m pytest -rs "$@"

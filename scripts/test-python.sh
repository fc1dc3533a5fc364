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
# One wheel (abi3: any CPython 3.9+, NumPy 1.x or 2.x), installed into this venv and, for the
# pyrender comparison, into pyrender's.
wheels="$target/python-wheels"
rm -rf "$wheels"
CARGO_TARGET_DIR="$target" MATURIN_PEP517_ARGS="--profile $profile" \
  "$venv/bin/python" -m pip wheel --quiet --disable-pip-version-check --no-deps -w "$wheels" ./python
wheel="$(ls "$wheels"/meshtracer-*.whl)"
"$venv/bin/python" -m pip install --quiet --disable-pip-version-check --force-reinstall --no-deps "$wheel"
echo "python package built and installed ($profile profile) in $(( $(date +%s) - start )) s"

cli="${MESHTRACER_CLI:-$target/debug/meshtracer}"
cd python/tests
# test_pyrender_front.py needs pyrender, which lives in its own venv (numpy<2, PyOpenGL 3.1.7:
# scripts/reference/install_pyrender.sh): it runs there when MESHTRACER_PYRENDER_PYTHON names
# that venv's python, and skips with its reason here otherwise.
pyrender_python="${MESHTRACER_PYRENDER_PYTHON:-}"
ignore=()
if [ -n "$pyrender_python" ]; then
  ignore=(--ignore=test_pyrender_front.py)
fi
MESHTRACER_CLI="$cli" "$venv/bin/python" -m pytest -rs "${ignore[@]}" "$@"
if [ -n "$pyrender_python" ]; then
  "$pyrender_python" -m pip install --quiet --disable-pip-version-check "pytest>=7"
  "$pyrender_python" -m pip install --quiet --disable-pip-version-check --force-reinstall --no-deps "$wheel"
  MESHTRACER_CLI="$cli" "$pyrender_python" -m pytest -rs test_pyrender_front.py "$@"
fi

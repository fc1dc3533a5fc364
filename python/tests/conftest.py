"""Shared fixtures: the meshtracer CLI the package is compared against, and the sample models.

- ``cli``: the ``meshtracer`` binary. ``MESHTRACER_CLI`` names it (CI sets it, and then a
  missing binary fails the tests instead of skipping them); else ``target/debug/meshtracer``
  or ``target/release/meshtracer`` under ``CARGO_TARGET_DIR`` or the repository's ``target``.
- ``samples``: the shared sample models (``MESHTRACER_SAMPLES``), as for ``cargo test``; the
  tests that need them skip with a notice without it.
"""

import os
import subprocess
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[2]
ASSETS = REPO / "assets"


def _find_cli():
    named = os.environ.get("MESHTRACER_CLI")
    if named:
        path = Path(named)
        if not (path.is_file() and os.access(path, os.X_OK)):
            pytest.fail(f"MESHTRACER_CLI={named} is not an executable file")
        return path
    target = Path(os.environ.get("CARGO_TARGET_DIR", REPO / "target"))
    for profile in ("debug", "release"):
        path = target / profile / "meshtracer"
        if path.is_file():
            return path
    return None


@pytest.fixture(scope="session")
def cli():
    path = _find_cli()
    if path is None:
        pytest.skip("SKIPPED: no meshtracer binary (build it with `cargo build`, or set MESHTRACER_CLI)")

    def run(*args, check=True):
        result = subprocess.run([str(path), *map(str, args)], capture_output=True, text=True)
        if check and result.returncode != 0:
            pytest.fail(f"{path} {' '.join(map(str, args))} failed:\n{result.stderr}")
        return result

    return run


@pytest.fixture(scope="session")
def samples():
    folder = os.environ.get("MESHTRACER_SAMPLES")
    if not folder:
        pytest.skip("SKIPPED: MESHTRACER_SAMPLES is not set (the shared sample models)")
    return Path(folder)


def cli_error_message(result):
    """The message of a failed CLI run: its last stderr line without `meshtracer: error: `."""
    assert result.returncode != 0, result
    last = result.stderr.strip().splitlines()[-1]
    prefix = "meshtracer: error: "
    assert last.startswith(prefix), result.stderr
    return last[len(prefix):]

#!/usr/bin/env bash
# Installs pyrender for headless use into a virtual environment (default .ci/venv) and prints
# the python to use. Needs Debian's libosmesa6 (installed here when running as root).
set -euo pipefail
venv="${1:-$(cd "$(dirname "$0")/../.." && pwd)/.ci/venv}"
if ! ldconfig -p 2>/dev/null | grep -q libOSMesa; then
  if [ "$(id -u)" = 0 ]; then
    apt-get update -qq >/dev/null
    DEBIAN_FRONTEND=noninteractive apt-get install -y -qq --no-install-recommends libosmesa6 >/dev/null
  else
    echo "libosmesa6 is missing: sudo apt-get install libosmesa6" >&2
    exit 1
  fi
fi
check='import os; os.environ["PYOPENGL_PLATFORM"] = "osmesa"; import pyrender, trimesh, networkx; from OpenGL.osmesa import OSMesaCreateContextAttribs'
if ! "$venv/bin/python" -c "$check" 2>/dev/null; then
  python3 -m venv "$venv"
  "$venv/bin/pip" install -q --disable-pip-version-check pyrender==0.1.45
  "$venv/bin/pip" install -q --disable-pip-version-check -r "$(dirname "$0")/requirements.txt" 2>&1 | grep -v "dependency conflicts\|requires\|resolver" || true
fi
"$venv/bin/python" -c "$check" >/dev/null
echo "$venv/bin/python"

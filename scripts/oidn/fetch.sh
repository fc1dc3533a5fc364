#!/usr/bin/env bash
# Installs Intel Open Image Denoise 2.5.1 (CPU device) for `cargo build --features denoise`,
# reproducibly, from a registry package: the `pyoidn` 2.5.1.0 wheel on PyPI, which ships the
# library's release build. The wheel's SHA-256 is pinned (the digest PyPI publishes for
# pyoidn-2.5.1.0-py3-none-manylinux2014_x86_64.whl), so the same bytes are installed on every
# machine or the script stops.
#
# Usage:
#   eval "$(scripts/oidn/fetch.sh [DEST])"     # installs into DEST, exports OIDN_DIR=DEST
#   cargo build --release --features denoise
#
# DEST defaults to scripts/oidn/OpenImageDenoise-2.5.1 in this repository (ignored by git).
# It gets the layout the `oidn` crate's build script expects of OIDN_DIR: DEST/lib holds
# libOpenImageDenoise.so (a symlink to the versioned library), its core library, the CPU device
# module and TBB. GPU device modules (CUDA, HIP, SYCL; 45 MB more) are left out: meshtracer
# denoises on the CPU. meshtracer's build script records DEST/lib as the binary's run path,
# so the binary runs without LD_LIBRARY_PATH (as long as DEST stays where it is).
#
# PYOIDN_WHEEL=/path/to/pyoidn-2.5.1.0-py3-none-manylinux2014_x86_64.whl uses a wheel already
# downloaded (checked against the same digest) instead of asking pip.
#
# Only the shell commands for the caller go to standard output; progress goes to standard error.
set -euo pipefail

VERSION=2.5.1.0
WHEEL=pyoidn-${VERSION}-py3-none-manylinux2014_x86_64.whl
SHA256=32ad13368f8de1ef63001942ad05b02a00cd732d1206d97f352d3a3f606d823e
LIBRARIES=(
    libOpenImageDenoise.so.2.5.1
    libOpenImageDenoise_core.so.2.5.1
    libOpenImageDenoise_device_cpu.so.2.5.1
    libtbb.so.12.19
)

say() { echo "fetch.sh: $*" >&2; }
die() { say "error: $*"; exit 1; }

if [ "$(uname -s)" != Linux ] || [ "$(uname -m)" != x86_64 ]; then
    die "this script installs the Linux x86_64 library; on $(uname -sm) install Open Image Denoise 2.x yourself and set OIDN_DIR (see docs/denoising.md)"
fi
for tool in sha256sum unzip; do
    command -v "$tool" >/dev/null || die "needs $tool"
done

here=$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)
dest=$(realpath -m "${1:-$here/OpenImageDenoise-2.5.1}")
stamp=$dest/wheel.sha256
# DEST is replaced as a whole below: never a folder this script did not make.
if [ -e "$dest" ] && [ ! -f "$stamp" ] && [ -n "$(ls -A "$dest" 2>/dev/null || echo x)" ]; then
    die "$dest exists and is not an installation made by this script; choose another DEST"
fi
mkdir -p "$(dirname "$dest")"

if [ -f "$stamp" ] && [ "$(cat "$stamp")" = "$SHA256" ] && [ -e "$dest/lib/libOpenImageDenoise.so" ]; then
    say "Open Image Denoise 2.5.1 already installed in $dest"
else
    work=$(mktemp -d)
    trap 'rm -rf "$work"' EXIT
    if [ -n "${PYOIDN_WHEEL:-}" ]; then
        [ -f "$PYOIDN_WHEEL" ] || die "PYOIDN_WHEEL=$PYOIDN_WHEEL: no such file"
        wheel=$PYOIDN_WHEEL
    else
        command -v pip >/dev/null || die "needs pip (or PYOIDN_WHEEL=path to $WHEEL)"
        say "downloading $WHEEL from PyPI (87 MB)"
        # --platform/--only-binary: the Linux x86_64 wheel whatever the host Python is; pip
        # checks the hash itself too (--require-hashes is implied by the --hash option).
        echo "pyoidn==$VERSION --hash=sha256:$SHA256" >"$work/requirements.txt"
        pip download --no-deps --only-binary=:all: --platform manylinux2014_x86_64 \
            --dest "$work" --requirement "$work/requirements.txt" >&2 ||
            die "pip download pyoidn==$VERSION failed"
        wheel=$work/$WHEEL
        [ -f "$wheel" ] || die "pip did not write $WHEEL"
    fi
    actual=$(sha256sum "$wheel" | cut -d' ' -f1)
    [ "$actual" = "$SHA256" ] ||
        die "$wheel: SHA-256 $actual, expected $SHA256 (not the wheel PyPI published; nothing installed)"
    say "wheel verified (SHA-256 $SHA256)"

    # Extract into a fresh folder beside DEST, then swap it in: an interrupted run leaves the
    # previous installation (or none), never half of one.
    staging=$(mktemp -d "$dest.partial.XXXXXX")
    trap 'rm -rf "$work" "$staging"' EXIT
    chmod 755 "$staging"
    mkdir -p "$staging/lib"
    members=()
    for library in "${LIBRARIES[@]}"; do
        members+=("pyoidn/oidn/lib/$library")
    done
    unzip -q -j -o "$wheel" "${members[@]}" -d "$staging/lib" ||
        die "$wheel: cannot extract ${LIBRARIES[*]}"
    unzip -q -j -o "$wheel" "pyoidn-$VERSION.dist-info/licenses/LICENSE" -d "$staging" ||
        die "$wheel: cannot extract its LICENSE"
    mv "$staging/LICENSE" "$staging/LICENSE.pyoidn"
    # The wheel stores each library under its versioned name and again under every alias (a zip
    # has no symlinks); recreate the aliases as links so each library is on disk once.
    ln -s libOpenImageDenoise.so.2.5.1 "$staging/lib/libOpenImageDenoise.so.2"
    ln -s libOpenImageDenoise.so.2 "$staging/lib/libOpenImageDenoise.so"
    ln -s libtbb.so.12.19 "$staging/lib/libtbb.so.12"
    ln -s libtbb.so.12 "$staging/lib/libtbb.so"
    echo "$SHA256" >"$staging/wheel.sha256"
    rm -rf "$dest"
    mv "$staging" "$dest"
    say "installed Open Image Denoise 2.5.1 (CPU device, TBB) into $dest"
fi

# The libraries find each other through their own run path ($ORIGIN/../lib); check that the
# CPU device actually loads here (a missing libstdc++ or an old glibc shows up now, not at the
# first --denoise).
if command -v python3 >/dev/null; then
    python3 - "$dest/lib/libOpenImageDenoise.so" >&2 <<'EOF' || die "the installed library does not load or has no CPU device (see above)"
import ctypes, sys
lib = ctypes.CDLL(sys.argv[1])
lib.oidnNewDevice.restype = ctypes.c_void_p
lib.oidnNewDevice.argtypes = [ctypes.c_int]
lib.oidnCommitDevice.argtypes = [ctypes.c_void_p]
lib.oidnGetDeviceError.argtypes = [ctypes.c_void_p, ctypes.POINTER(ctypes.c_char_p)]
lib.oidnGetDeviceInt.argtypes = [ctypes.c_void_p, ctypes.c_char_p]
lib.oidnReleaseDevice.argtypes = [ctypes.c_void_p]
OIDN_DEVICE_TYPE_CPU = 1
device = lib.oidnNewDevice(OIDN_DEVICE_TYPE_CPU)
message = ctypes.c_char_p()
if not device:
    lib.oidnGetDeviceError(None, ctypes.byref(message))
    sys.exit(f"no CPU device: {message.value}")
lib.oidnCommitDevice(device)
if lib.oidnGetDeviceError(device, ctypes.byref(message)) != 0:
    sys.exit(f"CPU device: {message.value}")
version = lib.oidnGetDeviceInt(device, b"version")
lib.oidnReleaseDevice(device)
print(f"fetch.sh: the CPU device loads (Open Image Denoise {version // 10000}.{version // 100 % 100}.{version % 100})")
EOF
fi

echo "export OIDN_DIR='$dest'"
echo "# No LD_LIBRARY_PATH needed for meshtracer (its build script sets the run path); other"
echo "# programs linked against this copy need LD_LIBRARY_PATH='$dest/lib'."

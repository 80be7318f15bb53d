#!/usr/bin/env bash
# Set up a Debian 12 machine for abbe: system packages and the Python venv.
# Idempotent: installs only what is missing. Run as root (CI) or with sudo.
#   ./scripts/setup.sh
set -euo pipefail

REPO="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
cd "$REPO"

PACKAGES=(
    cmake build-essential pkg-config
    libcmocka-dev libmodbus-dev
    gcc-arm-none-eabi libnewlib-arm-none-eabi
    qemu-system-arm
    valgrind
    clang libclang-rt-14-dev
    socat can-utils
    linuxcnc-uspace linuxcnc-uspace-dev
    python3 python3-venv
    postgresql
    chromium fonts-dejavu-core
    lld
    frama-c-base why3 z3 cvc4 cppcheck clang-tidy-14
)

log() { printf '[setup] %s\n' "$*"; }

missing=()
for pkg in "${PACKAGES[@]}"; do
    if ! dpkg-query -W -f='${Status}' "$pkg" 2>/dev/null | grep -q 'install ok installed'; then
        missing+=("$pkg")
    fi
done

if ((${#missing[@]})); then
    SUDO=()
    if [[ $(id -u) -ne 0 ]]; then
        command -v sudo >/dev/null || { echo "[setup] need root or sudo to install: ${missing[*]}" >&2; exit 1; }
        SUDO=(sudo)
    fi
    log "installing: ${missing[*]}"
    export DEBIAN_FRONTEND=noninteractive
    "${SUDO[@]}" apt-get update -q
    "${SUDO[@]}" apt-get install -y -q --no-install-recommends "${missing[@]}" </dev/null
else
    log "system packages: all present"
fi

# Python: a venv at <repo>/.venv with the pinned environment of
# host_tools/requirements.lock (versions and hashes; refresh it with
# scripts/lock.sh) and host_tools installed editable on top, without
# dependencies of its own and without running CMake (the library comes from
# build/). Re-installs only when the lock or pyproject.toml changed.
VENV="$REPO/.venv"
PYTHON="${ABBE_PYTHON:-python3}"
LOCK="host_tools/requirements.lock"
if [[ ! -x "$VENV/bin/python" ]]; then
    log "creating $VENV"
    "$PYTHON" -m venv "$VENV"
fi
stamp="$VENV/.abbe-host-tools.sha256"
# the editable install maps each module of abbe to its file once: a module that
# becomes a package (abbe/model/clib.py -> clib/) or goes away needs a reinstall,
# so the list of the package's files is part of the stamp
want="$({ cat host_tools/pyproject.toml "$LOCK"; (cd host_tools && find abbe -name '*.py' | LC_ALL=C sort); } | sha256sum | cut -d' ' -f1)"
if [[ ! -f "$stamp" || "$(cat "$stamp")" != "$want" ]] || ! "$VENV/bin/python" -c 'import abbe' 2>/dev/null; then
    log "installing $LOCK into $VENV"
    "$VENV/bin/python" -m pip install -q --require-hashes --no-deps -r "$LOCK" </dev/null
    log "installing host_tools (editable) into $VENV"
    "$VENV/bin/python" -m pip install -q --no-deps --no-build-isolation -e host_tools </dev/null
    "$VENV/bin/python" -m pip check
    echo "$want" >"$stamp"
else
    log "python venv: up to date"
fi
log "done"

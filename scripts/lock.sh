#!/usr/bin/env bash
# Refresh host_tools/requirements.lock: the pinned versions (with hashes) of the
# test, demo and build environment that scripts/setup.sh installs. The package's
# own dependencies (host_tools/pyproject.toml) stay ranges; this file pins one
# tested set of them so a commit passes or fails the same way on any day.
#   ./scripts/lock.sh             keep the current pins, add what is missing
#   ./scripts/lock.sh --upgrade   move every pin to the newest release allowed
# Then run ./scripts/test.sh and commit the lock with the change that needed it.
set -euo pipefail

REPO="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
PYTHON="${ABBE_PYTHON:-python3}"
PIP_TOOLS_VERSION="7.6.2"

tmp="$(mktemp -d)"
trap 'rm -rf "$tmp"' EXIT
"$PYTHON" -m venv "$tmp/venv"
"$tmp/venv/bin/python" -m pip install -q "pip-tools==$PIP_TOOLS_VERSION"
cd "$REPO/host_tools"
"$tmp/venv/bin/pip-compile" --quiet --generate-hashes --allow-unsafe --strip-extras \
    --no-emit-index-url --no-emit-find-links --extra test --extra ports --extra history --extra thermal --extra klipper --build-deps-for wheel \
    --output-file requirements.lock "$@" pyproject.toml
echo "[lock] wrote host_tools/requirements.lock"

#!/usr/bin/env bash
# Install abbe's Klipper module the way Klipper plugins are installed: a link
# from Klipper's klippy/extras/ to port/klipper/abbe.py (a `git pull` of abbe
# then updates it). Restart Klipper afterwards.
#   port/klipper/install.sh [KLIPPER_DIR]     (default ~/klipper)
set -euo pipefail
HERE="$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)"
KLIPPER="${1:-$HOME/klipper}"
EXTRAS="$KLIPPER/klippy/extras"
[[ -d "$EXTRAS" ]] || { echo "install.sh: $EXTRAS: not a Klipper tree (give its path)" >&2; exit 2; }
ln -sfn "$HERE/abbe.py" "$EXTRAS/abbe.py"
echo "install.sh: linked $EXTRAS/abbe.py -> $HERE/abbe.py"

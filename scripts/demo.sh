#!/usr/bin/env bash
# The main job: set up, build the C library (build/), then evaluate the
# bundled example table (the paper's machine, examples/paper_table/) at a few
# machine positions with the float64 Python reference and the C library's
# f32 and fixed-point variants side by side.
#   ./scripts/demo.sh
set -euo pipefail

REPO="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
cd "$REPO"
JOBS="$(nproc 2>/dev/null || echo 2)"

bash scripts/setup.sh
cmake -S . -B build -DCMAKE_BUILD_TYPE=Release >/dev/null
cmake --build build -j "$JOBS" >/dev/null
export ABBE_LIB="$REPO/build/lib/libabbe.so"
ABBE="$REPO/.venv/bin/abbe"
MODEL=examples/paper_table/model.bin

echo "== abbe table info $MODEL"
"$ABBE" table info "$MODEL"
echo
echo "== abbe table eval $MODEL ... --clib   (positions mm, errors um)"
# Reference point (error 0 by construction), travel corners, the paper's
# ballbar centre, the middle of the travel.
"$ABBE" table eval "$MODEL" \
    163.626 -212.772 -290.704 \
    0 0 0 \
    500 -400 -300 \
    343.507 -285.090 -286.430 \
    250 -200 -150 \
    --clib

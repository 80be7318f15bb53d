#!/usr/bin/env bash
# The main job: set up, build the C library (build/), then run the demo
# pipeline on the bundled example machine (examples/vmc500/, the paper's
# geometry): fit the 6D laser lines -> tables (blob, C, JSON) -> build check ->
# predict the ballbar circle through the C library -> diagnose what the model
# misses -> compensate in the loop with the C compensator. Writes the HTML
# report to demo-out/index.html and the figures to demo-out/summary.json; then the
# five-axis demo into demo-out/five-axis/ (figures: demo-out/five-axis.json).
#   ./scripts/demo.sh
set -euo pipefail

REPO="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
cd "$REPO"
JOBS="$(nproc 2>/dev/null || echo 2)"

bash scripts/setup.sh
cmake -S . -B build -DCMAKE_BUILD_TYPE=Release >/dev/null
cmake --build build -j "$JOBS" >/dev/null
export ABBE_LIB="$REPO/build/lib/libabbe.so"

"$REPO/.venv/bin/abbe" demo -o demo-out --json demo-out/summary.json
echo "report: $REPO/demo-out/index.html"
# The five-axis part: the trunnion5ax_complete plan (probing, R-test, indexer, a datum
# sphere at a second height) identified whole and compared with its truth.
"$REPO/.venv/bin/abbe" demo --five-axis -o demo-out/five-axis --json demo-out/five-axis.json
echo "five-axis report: $REPO/demo-out/five-axis/report/index.html"

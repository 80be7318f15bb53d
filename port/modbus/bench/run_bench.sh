#!/usr/bin/env bash
# Benchmark abbe-modbusd on TCP loopback: request round trip (median, p99),
# upload of the largest table, and a 1 kHz position/correction exchange
# checked cycle by cycle, natively and with the server under valgrind memcheck.
#
#   port/modbus/bench/run_bench.sh [--full] [BUILD_DIR]
#
# Short (default, what CI runs through ctest -L bench): 2 s exchanges.
# Full (by hand): 60 s exchanges, 20000 round trips, 50 uploads.
# BUILD_DIR (default build-bench/) is configured Release, without sanitizers
# (valgrind and ASan do not mix), with -DABBE_BUILD_PORTS=ON.
set -euo pipefail
REPO="$(cd "$(dirname "${BASH_SOURCE[0]}")/../../.." && pwd)"
full=0
if [[ "${1:-}" == "--full" ]]; then
    full=1
    shift
fi
BUILD="${1:-$REPO/build-bench}"

cmake -S "$REPO" -B "$BUILD" -DCMAKE_BUILD_TYPE=Release -DABBE_BUILD_PORTS=ON \
      -DABBE_SANITIZE=OFF >/dev/null
cmake --build "$BUILD" -j "$(nproc 2>/dev/null || echo 2)" --target modbus_bench abbe-modbusd >/dev/null
BENCH="$(find "$BUILD" -name modbus_bench -type f -perm -u+x | head -n 1)"

if ((full)); then
    args=(--duration 60 --rtt 20000 --uploads 50)
    vargs=(--valgrind --duration 60 --rtt 1000 --uploads 5)
else
    args=(--duration 2 --rtt 2000 --uploads 10)
    vargs=(--valgrind --duration 2 --rtt 200 --uploads 2)
fi
status=0
"$BENCH" "${args[@]}" || status=1
if command -v valgrind >/dev/null; then
    "$BENCH" "${vargs[@]}" || status=1
else
    echo "valgrind not installed: memcheck run skipped"
fi
exit $status

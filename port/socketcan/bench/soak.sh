#!/bin/sh
# Soak / latency run of abbe-cand over a socketpair bus (can_bench is the bus).
#
#   port/socketcan/bench/soak.sh [--seconds S] [--rate HZ] [--valgrind] [--bin DIR] [--config FILE]
#
# Defaults: 60 s at 1 kHz (the full soak; CI runs --seconds 5), binaries from
# build/bin, configuration bench/bench.toml (the example table, default frame
# map). --rate 0 runs back to back (latency only). --valgrind runs the daemon
# under valgrind --leak-check=full (needs a build without ABBE_SANITIZE); any
# valgrind error or leak makes the daemon exit 99 and the run fail.
#
# Fails (exit 1) on a missed cycle (no complete answer within 1 s), a gap in
# the status sequence or a daemon exit status other than 0. Latency and
# overruns are reported, never asserted.
set -eu

here=$(cd "$(dirname "$0")" && pwd)
seconds=60
rate=1000
valgrind=0
bin="$here/../../../build/bin"
config="$here/bench.toml"
while [ $# -gt 0 ]; do
    case "$1" in
        --seconds) seconds=$2; shift 2 ;;
        --rate) rate=$2; shift 2 ;;
        --valgrind) valgrind=1; shift ;;
        --bin) bin=$2; shift 2 ;;
        --config) config=$2; shift 2 ;;
        -h|--help) sed -n '2,17p' "$0"; exit 0 ;;
        *) echo "soak.sh: unknown option $1" >&2; exit 2 ;;
    esac
done
for f in "$bin/abbe-cand" "$bin/can_bench"; do
    [ -x "$f" ] || { echo "soak.sh: $f not built (cmake -DABBE_BUILD_PORTS=ON)" >&2; exit 2; }
done

echo "soak.sh: $seconds s at $rate Hz, valgrind $valgrind, daemon $bin/abbe-cand"
if [ "$valgrind" = 1 ]; then
    exec "$bin/can_bench" --seconds "$seconds" --rate "$rate" -- \
        valgrind -q --error-exitcode=99 --leak-check=full --show-leak-kinds=all \
        --errors-for-leak-kinds=all "$bin/abbe-cand" -c "$config"
fi
exec "$bin/can_bench" --seconds "$seconds" --rate "$rate" -- "$bin/abbe-cand" -c "$config"

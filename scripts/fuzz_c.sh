#!/usr/bin/env bash
# Longer libFuzzer runs of the C harnesses than CI's (scripts/test.sh runs each
# for seconds: `ctest -L fuzz` in build-fuzz/).
#
#   scripts/fuzz_c.sh [--seconds S] [--jobs N] [HARNESS...]
#
# HARNESS: fuzz_model_load, fuzz_five_load, fuzz_thermal_load, fuzz_can_node,
# fuzz_can_config, fuzz_modbus_regs (default: all). Each runs S seconds
# (default 600) on N processes (default 1; the machine is shared), from its
# seeds and committed regressions, with a corpus that persists across runs in
# build-fuzz/long/<harness>/corpus.
# A finding is written to build-fuzz/long/<harness>/ (crash-*, timeout-*,
# oom-*) and makes the script exit 1; reproduce it with
# `build-fuzz/.../<harness> FILE`, then copy it into the harness'
# regressions/ folder (named after what it exposed) once fixed.
# With N > 1, libFuzzer's per-job logs (fuzz-<k>.log, written in its working
# directory) go to build-fuzz/long/<harness>/ too: each harness runs there.
# At the end: executions, executions per second and corpus size per harness.
set -uo pipefail

REPO="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
cd "$REPO"
SECONDS_PER=600
JOBS=1
HARNESSES=()
while (($#)); do
    case "$1" in
    --seconds) SECONDS_PER="$2"; shift 2 ;;
    --jobs) JOBS="$2"; shift 2 ;;
    -h | --help) sed -n '2,18p' "$0"; exit 0 ;;
    -*) echo "fuzz_c.sh: unknown option $1" >&2; exit 2 ;;
    *) HARNESSES+=("$1"); shift ;;
    esac
done
if ! [[ "$SECONDS_PER" =~ ^[0-9]+$ && "$JOBS" =~ ^[1-9][0-9]*$ ]]; then
    echo "fuzz_c.sh: --seconds wants a number of seconds, --jobs a count >= 1" >&2
    exit 2
fi
((${#HARNESSES[@]})) || HARNESSES=(fuzz_model_load fuzz_five_load fuzz_thermal_load fuzz_can_node fuzz_can_config fuzz_modbus_regs)

BUILD=build-fuzz
CC=clang cmake -S . -B "$BUILD" -DCMAKE_BUILD_TYPE=RelWithDebInfo -DABBE_BUILD_FUZZ=ON -DABBE_BUILD_TESTS=OFF >/dev/null &&
    cmake --build "$BUILD" -j "$JOBS" >/dev/null || { echo "fuzz_c.sh: build failed" >&2; exit 1; }

# harness -> "binary|seed dirs..."
corpus_of() {
    case "$1" in
    fuzz_model_load) echo "$BUILD/fuzz/fuzz_model_load|$BUILD/fuzz/seeds fuzz/regressions" ;;
    # the five-axis and the thermal loaders: the same seeds (the golden tables,
    # five-axis and thermal ones among them) and regressions (fuzz/CMakeLists.txt)
    fuzz_five_load) echo "$BUILD/fuzz/fuzz_five_load|$BUILD/fuzz/seeds fuzz/regressions" ;;
    fuzz_thermal_load) echo "$BUILD/fuzz/fuzz_thermal_load|$BUILD/fuzz/seeds fuzz/regressions" ;;
    fuzz_can_node) echo "$BUILD/fuzz/port-socketcan/fuzz_can_node|$BUILD/fuzz/port-socketcan/seeds-node port/socketcan/fuzz/regressions" ;;
    fuzz_can_config) echo "$BUILD/fuzz/port-socketcan/fuzz_can_config|port/socketcan/fuzz/seeds/config port/socketcan/fuzz/regressions" ;;
    fuzz_modbus_regs) echo "$BUILD/fuzz/port-modbus/fuzz_modbus_regs|$BUILD/fuzz/port-modbus/seeds port/modbus/fuzz/regressions" ;;
    *) return 1 ;;
    esac
}

found=0
declare -a SUMMARY=()
for h in "${HARNESSES[@]}"; do
    spec="$(corpus_of "$h")" || { echo "fuzz_c.sh: unknown harness $h" >&2; exit 2; }
    bin="${spec%%|*}"
    read -r -a seeds <<<"${spec#*|}"
    out="$REPO/$BUILD/long/$h"
    mkdir -p "$out/corpus"
    log="$out/run.log"
    echo "[fuzz] $h: $SECONDS_PER s x $JOBS job(s), log $log"
    args=(-max_total_time="$SECONDS_PER" -timeout=10 -print_final_stats=1 -artifact_prefix="$out/")
    if ((JOBS > 1)); then
        args+=(-jobs="$JOBS" -workers="$JOBS")
    fi
    # run in $out (libFuzzer's -jobs logs land in its working directory), every path absolute
    seeds=("${seeds[@]/#/$REPO/}")
    (cd "$out" && ASAN_OPTIONS=detect_leaks=1 UBSAN_OPTIONS=print_stacktrace=1:halt_on_error=1 \
        "$REPO/$bin" "${args[@]}" "$out/corpus" "${seeds[@]}") >"$log" 2>&1
    rc=$?
    runs=$(grep -h 'stat::number_of_executed_units' "$log" "$out"/fuzz-*.log 2>/dev/null | awk '{s += $2} END {print s + 0}')
    rate=$(grep -h 'stat::average_exec_per_sec' "$log" "$out"/fuzz-*.log 2>/dev/null | awk '{s += $2} END {print s + 0}')
    files=$(find "$out/corpus" -type f | wc -l)
    artifacts=$(find "$out" -maxdepth 1 -type f \( -name 'crash-*' -o -name 'timeout-*' -o -name 'oom-*' -o -name 'leak-*' \) | wc -l)
    if ((rc != 0 || artifacts > 0)); then
        found=1
        SUMMARY+=("FOUND $h: exit $rc, $artifacts finding(s) in $out/ (see $log)")
    else
        SUMMARY+=("ok    $h: $runs inputs, $rate exec/s, corpus $files files")
    fi
done
echo
printf '%s\n' "${SUMMARY[@]}"
exit $found

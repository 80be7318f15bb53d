#!/usr/bin/env bash
# Per-kind five-axis images (issue 39 item 4): the library built with -DABBE_FIVE_KINDS=<k>
# for each kind alone and for the trunnion pair, the five-axis size images only
# (bench_size_five_f32 / _q), in <build>-kinds<k> next to build-bench-m4f / build-bench-m3.
# bench/report/five_axis.py (scripts/bench_five.py) reads their link maps when present.
#
#   bash scripts/bench_five_kinds.sh [build-bench-m4f build-bench-m3]
set -euo pipefail
cd "$(dirname "$0")/.."
m4f=${1:-build-bench-m4f}
m3=${2:-build-bench-m3}
for kinds in 1 2 "1;2" 3 4 5; do
    tag=${kinds//;/}
    for target in m4f m3; do
        build=$([ "$target" = m4f ] && echo "$m4f" || echo "$m3")-kinds$tag
        cmake -S . -B "$build" -DCMAKE_TOOLCHAIN_FILE=cmake/toolchain-cortex-$target.cmake \
            -DCMAKE_BUILD_TYPE=Release -DABBE_BUILD_BENCH=ON -DABBE_BUILD_TESTS=OFF \
            "-DABBE_FIVE_KINDS=$kinds" >/dev/null
        images=(bench_size_five_q)
        [ "$target" = m4f ] && images+=(bench_size_five_f32)
        cmake --build "$build" -j2 --target "${images[@]}" >/dev/null
        echo "built $build"
    done
done

#!/usr/bin/env bash
# Measure the library and write bench/results.md (see scripts/bench_report.py):
# x86-64 instructions per call (callgrind), Cortex-M4F/M3 instructions per
# call (QEMU exec trace), flash, static RAM and stack, against a naive
# double-precision reference. Builds in build-bench-{host,m4f,m3,m4f-os,m3-os}/,
# build-bench-{host,m4f,m3}-1.0/ (format 1.0 libraries: what the reversal blocks cost),
# and build-bench-{m4f,m3}-clang/ + build-bench-m4f-clang-nounroll/ (clang/LLVM).
#   ./scripts/bench.sh            # writes bench/results.md
#   ./scripts/bench.sh -o FILE    # writes FILE instead (without section 9: port/grblhal/bench/cost.py)
set -euo pipefail

REPO="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
cd "$REPO"
JOBS="$(nproc 2>/dev/null || echo 2)"
OUT="bench/results.md"
if [[ "${1:-}" == "-o" && -n "${2:-}" ]]; then
    OUT="$2"
fi

bash scripts/setup.sh

common=(-DCMAKE_BUILD_TYPE=Release -DABBE_BUILD_BENCH=ON -DABBE_BUILD_TESTS=OFF -DABBE_STACK_USAGE=ON)
cmake -S . -B build-bench-host "${common[@]}" >/dev/null
cmake -S . -B build-bench-m4f -DCMAKE_TOOLCHAIN_FILE=cmake/toolchain-cortex-m4f.cmake "${common[@]}" >/dev/null
cmake -S . -B build-bench-m3 -DCMAKE_TOOLCHAIN_FILE=cmake/toolchain-cortex-m3.cmake "${common[@]}" >/dev/null
# format 1.0 libraries (-DABBE_WITH_REVERSAL=OFF): what format 1.1's reversal blocks cost
cmake -S . -B build-bench-host-1.0 "${common[@]}" -DABBE_WITH_REVERSAL=OFF >/dev/null
cmake -S . -B build-bench-m4f-1.0 -DCMAKE_TOOLCHAIN_FILE=cmake/toolchain-cortex-m4f.cmake "${common[@]}" \
    -DABBE_WITH_REVERSAL=OFF >/dev/null
cmake -S . -B build-bench-m3-1.0 -DCMAKE_TOOLCHAIN_FILE=cmake/toolchain-cortex-m3.cmake "${common[@]}" \
    -DABBE_WITH_REVERSAL=OFF >/dev/null
size=(-DCMAKE_BUILD_TYPE=MinSizeRel -DABBE_BUILD_BENCH=ON -DABBE_BUILD_TESTS=OFF -DABBE_STACK_USAGE=ON)
cmake -S . -B build-bench-m4f-os -DCMAKE_TOOLCHAIN_FILE=cmake/toolchain-cortex-m4f.cmake "${size[@]}" >/dev/null
cmake -S . -B build-bench-m3-os -DCMAKE_TOOLCHAIN_FILE=cmake/toolchain-cortex-m3.cmake "${size[@]}" >/dev/null
# clang/LLVM (section 9), and once without loop unrolling (what clang's flash is made of)
cmake -S . -B build-bench-m4f-clang -DCMAKE_TOOLCHAIN_FILE=cmake/toolchain-cortex-m4f-clang.cmake "${common[@]}" >/dev/null
cmake -S . -B build-bench-m3-clang -DCMAKE_TOOLCHAIN_FILE=cmake/toolchain-cortex-m3-clang.cmake "${common[@]}" >/dev/null
cmake -S . -B build-bench-m4f-clang-nounroll -DCMAKE_TOOLCHAIN_FILE=cmake/toolchain-cortex-m4f-clang.cmake \
    "${common[@]}" "-DCMAKE_C_FLAGS_RELEASE=-O2 -DNDEBUG -fno-unroll-loops" >/dev/null
for dir in build-bench-host build-bench-m4f build-bench-m3 build-bench-m4f-os build-bench-m3-os \
    build-bench-host-1.0 build-bench-m4f-1.0 build-bench-m3-1.0 \
    build-bench-m4f-clang build-bench-m3-clang build-bench-m4f-clang-nounroll; do
    cmake --build "$dir" -j "$JOBS"
done
# Section 11's per-kind five-axis images (-DABBE_FIVE_KINDS=<k>: size images only)
bash scripts/bench_five_kinds.sh build-bench-m4f build-bench-m3

python3 scripts/bench_report.py --repo . --host build-bench-host --m4f build-bench-m4f \
    --m3 build-bench-m3 --m4f-os build-bench-m4f-os --m3-os build-bench-m3-os \
    --host-1.0 build-bench-host-1.0 --m4f-1.0 build-bench-m4f-1.0 --m3-1.0 build-bench-m3-1.0 \
    --m4f-clang build-bench-m4f-clang --m3-clang build-bench-m3-clang \
    --m4f-clang-nounroll build-bench-m4f-clang-nounroll -o "$OUT"
# Section 12 (the thermal block, format 1.3): appended to the file just written.
python3 scripts/bench_thermal.py --m4f build-bench-m4f --m3 build-bench-m3 --results "$OUT"
# Section 10 (the grblHAL plugin per segment) is written by its own script, into bench/results.md only.
if [[ $OUT == bench/results.md ]]; then
    .venv/bin/python port/grblhal/bench/cost.py
fi

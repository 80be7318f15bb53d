#!/usr/bin/env bash
# Run every abbe test: set-up, then
#   1. host build with ASan + UBSan (build-asan/): unit tests, golden vectors, checks,
#      the CAN and Modbus ports and their tests; the library's plain C kernels
#      (ABBE_PORTABLE_C: the SIMD ones run in steps 2 and 5)
#   2. host release build (build/, gives build/lib/libabbe.so and the port daemons
#      to Python) + its ctest
#   3. Cortex-M4F cross build (build-m4f/) + its ctest under QEMU
#   4. Cortex-M3 cross build (build-m3/), fixed point only, + its ctest under QEMU
#   5. libFuzzer run on the table loader (build-fuzz/, clang)
#   6. the Python import contracts (lint-imports: host_tools' one-way layers)
#   7. pytest host_tools/tests
#   8. the wheel: built from host_tools/, installed with the lock into a fresh venv
#      outside the checkout, abbe demo / fit / diagnose run there
#   9. LinuxCNC: the HAL component built and installed, halrun and simulator
#      tests, the xyzac-trt simulator with the trt export and the component in
#      five-axis mode (port/linuxcnc/tests/run.sh; halrun / linuxcnc run as an
#      unprivileged user, created when run as root)
#  10. clang/LLVM cross builds (build-m4f-clang/, build-m3-clang/: the same
#      golden vectors, C++ consumer and symbol checks under QEMU as steps 3-4)
#  11. measurement programs (abbe program, LinuxCNC dialect) run in LinuxCNC's
#      simulator: targets, approach sides, dwells, travel, the ballbar arc, and the
#      closed loop through a Renishaw .rtl file; the five-axis R-test (TCP) and
#      sphere-probing programs in the xyzac-trt sample (port/linuxcnc/tests/program_sim.py,
#      under flock /tmp/abbe-linuxcnc.lock); the ISO 230-3 spindle program's speeds and
#      phase times (port/linuxcnc/tests/spindle_sim.py)
#  12. grblHAL: the Simulator built with the abbe plugin from the snapshots in
#      third_party/grblhal, G-code checked against the Python reference,
#      uploads, the stored table over a restart, homing and soft limits;
#      the measurement programs (abbe program, grblHAL dialect) in the unmodified
#      Simulator (port/grblhal/tests/run.sh; the snapshots are in third_party/grblhal;
#      SKIPPED without them, a failure under CI=true)
#  13. Klipper: the module port/klipper/abbe.py in Klipper's batch mode (the snapshot in
#      third_party/klipper, an STM32F407 dictionary built with arm-none-eabi-gcc): move ends
#      and paths from the decoded MCU stream against abbe table eval, disabled = stock,
#      bad tables refused (port/klipper/tests/klipper_batch.py; SKIPPED without the snapshot)
#  14. the README's demo command (scripts/demo.sh), run twice: into a new
#      demo-out/ and over the old one
# CI time: the proofs and step 13 (Klipper) run in the background, one after the other, from
# step 7 (pytest) on, into steps 9-11 (LinuxCNC; scripts/lib/steps.sh step_bg); their output and
# summary lines come after step 11's, before step 12 (grblHAL). Runs every step even after a failure; exits non-zero
# if any step failed. The
# summary says PASS, SKIPPED (what is missing; a failure under CI=true) or FAIL
# per step, and lists the tests skipped inside a passing step (protocol:
# scripts/lib/steps.sh).
set -uo pipefail

REPO="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
cd "$REPO"
JOBS="$(nproc 2>/dev/null || echo 2)"
export CTEST_OUTPUT_ON_FAILURE=1
export CTEST_PARALLEL_LEVEL="$JOBS"

bash scripts/setup.sh || { echo "[test] FAIL: set-up failed"; exit 1; }

t_all=$SECONDS
# step, its outcomes (PASS / SKIPPED: exit 77 / FAIL) and the summary: scripts/lib/steps.sh
source scripts/lib/steps.sh

cmake_build() { # DIR [cmake args...]
    local dir="$1"
    shift
    cmake -S . -B "$dir" "$@" && cmake --build "$dir" -j "$JOBS"
}

ctest_in() { # DIR [ctest args...]: ctest, its skipped tests as notes for the summary
    local dir="$1" rc
    shift
    ctest --test-dir "$dir" --output-on-failure "$@" 2>&1 | tee "$dir/ctest.log"
    rc=$?
    ctest_skip_notes "$dir/ctest.log" "$dir"
    return $rc
}

host_asan() {
    cmake_build build-asan -DCMAKE_BUILD_TYPE=Debug -DABBE_SANITIZE=ON -DABBE_BUILD_PORTS=ON -DABBE_PORTABLE_C=ON &&
        ctest_in build-asan -j "$JOBS"
}

host_release() {
    cmake_build build -DCMAKE_BUILD_TYPE=Release -DABBE_BUILD_PORTS=ON &&
        ctest_in build -j "$JOBS"
}

cross() { # NAME TOOLCHAIN
    cmake_build "build-$1" -DCMAKE_TOOLCHAIN_FILE="cmake/toolchain-$2.cmake" -DCMAKE_BUILD_TYPE=Release &&
        ctest_in "build-$1" -j "$JOBS"
}

fuzz() {
    CC=clang cmake_build build-fuzz -DCMAKE_BUILD_TYPE=RelWithDebInfo \
        -DABBE_BUILD_FUZZ=ON -DABBE_BUILD_TESTS=OFF &&
        ctest_in build-fuzz -L fuzz
}

import_contracts() {
    (cd host_tools && "$REPO/.venv/bin/lint-imports")
}

pytest_all() { # -rs: the skips with their reasons, summed per reason into the summary
    local rc log="$REPO/build/pytest.log"
    mkdir -p build
    (cd host_tools && "$REPO/.venv/bin/python" -m pytest -q -rs -p no:cacheprovider \
        --ignore=tests/packaging tests) 2>&1 | tee "$log"
    rc=$?
    if [[ $rc -eq 5 ]]; then
        echo "[test] pytest collected no tests: nothing ran"
    fi
    pytest_skip_notes "$log"
    return $rc
}

wheel_test() {
    local rc log="$REPO/build/pytest-packaging.log"
    mkdir -p build
    (cd host_tools && "$REPO/.venv/bin/python" -m pytest -q -rs -s -p no:cacheprovider tests/packaging) 2>&1 |
        tee "$log"
    rc=$?
    pytest_skip_notes "$log"
    return $rc
}

cross_clang() { # both targets, each even if the other failed
    local rc=0
    cross m4f-clang cortex-m4f-clang || rc=1
    cross m3-clang cortex-m3-clang || rc=1
    return $rc
}

readme_demo() { # the README's other command, as a user runs it: fresh, then over its result
    local i
    for i in 1 2; do
        bash scripts/demo.sh || return 1
    done
    [[ -s demo-out/index.html && -s demo-out/summary.json ]] ||
        { echo "[test] demo-out/index.html or summary.json missing"; return 1; }
    if find . demo-out -maxdepth 1 -name '*.abbe-*' | grep .; then
        echo "[test] staging leftovers of the demo (above)"
        return 1
    fi
}

klipper_batch() { # Klipper from third_party/klipper, its host code on the project's venv (the lock has cffi, greenlet, jinja2)
    "$REPO/.venv/bin/python" port/klipper/tests/klipper_batch.py --json build-klipper/klipper.json
}

lcnc_component() { # one LinuxCNC on a machine at a time: the same lock as every LinuxCNC run here
    flock /tmp/abbe-linuxcnc.lock bash port/linuxcnc/tests/run.sh
}

lcnc_programs() { # as root, run.sh (step 9) created the unprivileged LinuxCNC user
    local rc=0
    flock /tmp/abbe-linuxcnc.lock /usr/bin/python3 port/linuxcnc/tests/program_sim.py \
        --json build-linuxcnc/programs.json || rc=1
    # the ISO 230-3 spindle program (2 speeds, 9 s on and 12.6 s off: ~1 min); a failure of either fails
    # the step (the step once reported only the last command's status)
    flock /tmp/abbe-linuxcnc.lock /usr/bin/python3 port/linuxcnc/tests/spindle_sim.py \
        --json build-linuxcnc/spindle.json || rc=1
    return $rc
}

step "host ASan+UBSan build and ctest (build-asan)" host_asan
step "host release build and ctest (build)" host_release
step "Cortex-M4F build and ctest under QEMU (build-m4f)" cross m4f cortex-m4f
step "Cortex-M3 build and ctest under QEMU (build-m3)" cross m3 cortex-m3
step "libFuzzer run (build-fuzz)" fuzz
step "Python import contracts (lint-imports)" import_contracts
# CI time: Klipper's step (batch mode: print time is not wall time, and klippy_drained.py makes
# its output complete however late the serial thread writes) and the proofs (CPU bound) run in the
# background, one after the other, from pytest on: pytest and the wheel take one core, the proofs
# the other (prove.sh's default is 2 jobs; its long proofs are bounded by steps, not wall time),
# and they end during LinuxCNC's steps (wall-clock bound: real-time simulator runs), so
# LinuxCNC's last steps run beside nothing. Their logs and outcomes appear after LinuxCNC's
# programs step (step_join). grblHAL's step stays in the foreground after them: its programs run
# on wall time (a 230 s deadline, dwell brackets) and failed once here when it shared the machine
# with LinuxCNC.
step_bg "Klipper module in Klipper's batch mode" klipper_batch
step_bg "proofs: Frama-C Eva, MISRA C:2012, clang-tidy (scripts/prove.sh, docs/proofs.md)" \
    ./scripts/prove.sh --lint --jobs 1
step "pytest host_tools/tests" pytest_all
step "wheel: build, install outside the checkout, run abbe there" wheel_test
step "LinuxCNC component: halrun and simulator tests" lcnc_component
step "clang Cortex-M4F and M3 builds and ctest under QEMU (build-m{4f,3}-clang)" cross_clang
step "measurement programs in LinuxCNC's simulator" lcnc_programs
step_join "Klipper module in Klipper's batch mode"
step_join "proofs: Frama-C Eva, MISRA C:2012, clang-tidy (scripts/prove.sh, docs/proofs.md)"
step "grblHAL plugin in grblHAL's Simulator" bash port/grblhal/tests/run.sh
step "README's demo command (scripts/demo.sh), twice" readme_demo

summary || exit 1

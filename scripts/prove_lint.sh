#!/usr/bin/env bash
# MISRA C:2012 (cppcheck's addon) and clang-tidy-14 (bugprone-*, cert-*,
# clang-analyzer-*) on lib/ and the ports' portable cores (docs/misra.md).
# A MISRA finding passes only if docs/misra.md's deviation table lists its
# rule for its file (tests/proofs/misra_deviations.txt is that table, machine
# readable); any clang-tidy finding fails. Prints each finding that fails.
#   ./scripts/prove_lint.sh
set -uo pipefail
REPO="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
cd "$REPO"
OUT="${ABBE_PROOF_OUT:-$REPO/build-proofs}"
mkdir -p "$OUT"

LIB=(lib/src/*.c)
# the ports' portable cores: what runs in a drive or controller, no OS calls
PORTS=(port/modbus/src/regs.c port/modbus/src/regs_render.c port/modbus/src/regs_upload.c port/modbus/src/regs_cycle.c
       port/modbus/src/regs_control.c port/socketcan/src/can_node.c port/socketcan/src/can_config_check.c
       port/socketcan/src/can_frame.c port/socketcan/src/can_status.c
       port/grblhal/src/abbe_grblhal_core.c port/grblhal/src/abbe_grblhal_core_eval.c
       port/grblhal/src/abbe_grblhal_core_line.c port/grblhal/src/abbe_grblhal_core_upload.c)
INC=(-Ilib/include -Ilib/src -Iport/modbus/include -Iport/socketcan/include -Iport/socketcan/src
     -Iport/grblhal/include)
DEV="tests/proofs/misra_deviations.txt"
fail=0

t0=$SECONDS
mkdir -p "$OUT/cppcheck"
cppcheck --addon=misra --std=c99 -q -j2 --cppcheck-build-dir="$OUT/cppcheck" "${INC[@]}" -DABBE_PORTABLE_C --platform=unix64 \
    --template='{file}:{line}: {id}: {message}' "${LIB[@]}" "${PORTS[@]}" 2>"$OUT/misra.txt"
# a finding: file:line: id: message; its rule must be deviated for a glob matching its file
awk -v dev="$DEV" '
    BEGIN { while ((getline l < dev) > 0) { if (l ~ /^#/ || l ~ /^[ \t]*$/) continue; split(l, f, /[ \t]+/); n++; rule[n] = f[1]; glob[n] = f[2] } }
    function covered(file, id,    i, g, hit) {
        for (i = 1; i <= n; i++) {
            if (id != "misra-c2012-" rule[i] && id != rule[i]) continue
            g = glob[i]; gsub(/\./, "\\.", g); gsub(/\*/, ".*", g)
            if (file ~ ("^" g "$")) { used[i] = 1; hit = 1 }
        }
        return hit
    }
    /^[^ ]+:[0-9]+: [A-Za-z0-9._-]+: / {
        split($0, p, ": "); split(p[1], fl, ":"); id = p[2]
        total++
        if (covered(fl[1], id)) { deviated++; next }
        bad++; print "[lint] MISRA/cppcheck: " $0
    }
    END {
        # a deviation no finding uses is stale (the code moved or was fixed): the list
        # says exactly where each rule is deviated, so it fails too
        for (i = 1; i <= n; i++) if (!(i in used)) { stale++; print "[lint] deviation listed, no finding: " rule[i] " " glob[i] " (" dev ")" }
        printf "[lint] cppcheck: %d findings, %d under a listed deviation, %d not; %d deviations, %d stale\n", total, deviated, bad, n, stale
        exit bad > 0 || stale > 0
    }
' "$OUT/misra.txt" || fail=1
echo "[lint] cppcheck $(cppcheck --version | cut -d" " -f2): $((SECONDS - t0)) s"

t0=$SECONDS
# two bugprone checks are heuristics about style, not defects (docs/misra.md):
# easily-swappable-parameters (API shape) and implicit-widening-of-multiplication-
# result (uint32 byte offsets, in range: the Eva proofs bound them). The loader's
# code lives in headers of static functions (model_load_*.h, included by
# model_load.c): without the header filter clang-tidy would not report there.
clang-tidy-14 --quiet -header-filter='lib/src/model_load_[a-z]+[.]h' -checks='-*,bugprone-*,cert-*,clang-analyzer-*,-bugprone-easily-swappable-parameters,-bugprone-implicit-widening-of-multiplication-result' \
    "${LIB[@]}" "${PORTS[@]}" \
    -- -std=c99 "${INC[@]}" -DABBE_PORTABLE_C >"$OUT/clang-tidy.txt" 2>&1
n=$(grep -c ': \(warning\|error\): ' "$OUT/clang-tidy.txt")
if ((n)); then
    grep ': \(warning\|error\): ' "$OUT/clang-tidy.txt" | sed 's/^/[lint] clang-tidy: /'
    fail=1
fi
echo "[lint] clang-tidy-14: $n findings ($((SECONDS - t0)) s)"
exit $fail

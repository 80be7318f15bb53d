# The steps of scripts/test.sh and their summary (sourced; tested by
# host_tools/tests/scripts/test_step_protocol.py with fake steps).
#
# Protocol: a step is a command; its exit status says what happened:
#   0    PASS     it ran and passed
#   77   SKIPPED  it could not run: something it needs is missing (the
#                 Automake / CTest convention for "skipped")
#   else FAIL
# A step writes what is missing, one line each, into the file named by
# $ABBE_TEST_NOTES (set by step for the step's duration). A step that ran may
# have left parts out (tests skipped inside it: pytest's, CTest's); it writes
# one note line for each and exits 0: the summary shows PASS and, below it,
# the skipped parts, each on a line starting with SKIPPED.
# Under CI=true a SKIPPED step is a failure (CI has everything beside the
# clone); skipped parts inside a passing step are listed, not failed (tests
# that must not skip in CI fail by themselves there: real data, see
# host_tools/tests/real_data.py).

declare -a RESULTS=()
failed=0
skipped=0

step() { # NAME COMMAND [ARGS...]
    local name="$1"
    shift
    local t0=$SECONDS rc notes line
    notes="$(mktemp)"
    echo
    echo "==== [test] $name ===="
    ABBE_TEST_NOTES="$notes" "$@"
    rc=$?
    local took="($((SECONDS - t0)) s)"
    if ((rc == 0)); then
        RESULTS+=("PASS     $name $took")
        while IFS= read -r line; do
            [[ -n $line ]] && RESULTS+=("         SKIPPED inside it: $line")
        done <"$notes"
    elif ((rc == 77)); then
        local why
        why="$(paste -sd ';' "$notes" | sed 's/;/; /g')"
        [[ -n $why ]] || why="the step named no reason"
        skipped=$((skipped + 1))
        if [[ ${CI:-} == true ]]; then
            RESULTS+=("SKIPPED  $name $took: $why (a failure under CI=true)")
            failed=$((failed + 1))
        else
            RESULTS+=("SKIPPED  $name $took: $why")
        fi
    else
        RESULTS+=("FAIL     $name $took")
        failed=$((failed + 1))
    fi
    rm -f "$notes"
}

# Tell the running step what was left out (one line); for steps that are
# shell functions of test.sh. Scripts write to "$ABBE_TEST_NOTES" themselves.
step_note() {
    [[ -n ${ABBE_TEST_NOTES:-} ]] && printf '%s\n' "$*" >>"$ABBE_TEST_NOTES"
    return 0
}

# Tests that CTest reports as skipped in LOG ("N - name (Skipped)"), as notes.
ctest_skip_notes() { # LOG DIR
    local names
    names="$(sed -n 's/^[[:space:]]*[0-9][0-9]* - \([^ ]*\) (Skipped)$/\1/p' "$1" | paste -sd ' ')"
    [[ -z $names ]] || step_note "$2: CTest skipped $(wc -w <<<"$names") test(s): $names"
}

# Pytest's skips in LOG (its -rs report, "SKIPPED [N] file:line: reason"),
# summed per reason, as notes.
pytest_skip_notes() { # LOG
    local line
    while IFS= read -r line; do
        step_note "pytest: $line"
    done < <(sed -n 's/^SKIPPED \[\([0-9]*\)\] [^ ]*: \(.*\)$/\1\t\2/p' "$1" |
        awk -F '\t' '{ n[$2] += $1 } END { for (r in n) printf "%d test(s): %s\n", n[r], r }' | sort -t: -k2)
}

# The summary; returns 1 if a step failed. The closing line is the runner's plain last line.
summary() {
    echo
    echo "==== [test] summary ===="
    printf '%s\n' "${RESULTS[@]}"
    local total=${#RESULTS[@]} n_steps=0 r
    for r in "${RESULTS[@]}"; do
        [[ $r == " "* ]] || n_steps=$((n_steps + 1))
    done
    if ((failed)); then
        echo "[test] FAILED: $failed of $n_steps steps failed ($((SECONDS - t_all)) s)"
        return 1
    fi
    if ((skipped)); then
        echo "[test] OK: $((n_steps - skipped)) of $n_steps steps passed, $skipped SKIPPED (above: what is missing) ($((SECONDS - t_all)) s)"
        return 0
    fi
    echo "[test] OK: all $n_steps steps passed ($((SECONDS - t_all)) s)"
}

# The steps of scripts/test.sh and their summary (sourced; tested by
# host_tools/tests/scripts/test_step_protocol.py with fake steps).
#
# Protocol: a step is a command; its exit status says what happened:
#   0    PASS     it ran and passed
#   77   SKIPPED  it could not run: something it needs is missing (the
#                 Automake / CTest convention for "skipped")
#   else FAIL     the summary shows the step's last $FAILED_TAIL_LINES lines of output
#                 under it (CI's record may keep only the summary)
# A step writes what is missing, one line each, into the file named by
# $ABBE_TEST_NOTES (set by step for the step's duration). A step that ran may
# have left parts out (tests skipped inside it: pytest's, CTest's); it writes
# one note line for each and exits 0: the summary shows PASS and, below it,
# the skipped parts, each on a line starting with SKIPPED.
# Under CI=true a SKIPPED step is a failure (CI has everything beside the
# clone); skipped parts inside a passing step are listed, not failed (tests
# that must not skip in CI fail by themselves there: real data, see
# host_tools/tests/real_data.py).
#
# Background steps (CI time): step_bg starts a step now, its output into its own log;
# step_join, called where the step stands in the run's order, waits for it, prints its
# log under its header and records its outcome exactly as step does (the summary keeps
# the run's order). Background steps run one after another (one lane: the machine has
# two cores; the foreground is meant to be a wall-clock bound step such as LinuxCNC's).

declare -a RESULTS=()
failed=0
skipped=0

step() { # NAME COMMAND [ARGS...]
    local name="$1"
    shift
    local t0=$SECONDS rc notes out tee_pid n=0
    notes="$(mktemp)"
    out="$(mktemp)"
    echo
    echo "==== [test] $name ===="
    # The output goes to the terminal as it comes and into OUT (a failed step's last lines
    # go into the summary). A redirection of this one command, not a pipe: a step that is a
    # shell function runs in this shell (its variables stay), and a process the step leaves
    # running (holding the pipe) cannot make the run wait: tee is waited for 5 s at most.
    ABBE_TEST_NOTES="$notes" "$@" > >(tee "$out") 2>&1
    rc=$?
    tee_pid=$!
    while kill -0 "$tee_pid" 2>/dev/null && ((n < 50)); do
        sleep 0.1
        n=$((n + 1))
    done
    record_step "$name" "$rc" "$((SECONDS - t0))" "$notes" "$out"
    rm -f "$notes" "$out"
}

#: How many of a failed step's last output lines the summary shows (CI's record keeps the
#: summary; the whole output may be cut).
FAILED_TAIL_LINES=${FAILED_TAIL_LINES:-25}

# The outcome of one step into RESULTS (PASS / SKIPPED / FAIL, the notes below a PASS).
record_step() { # NAME RC SECONDS NOTES_FILE [OUTPUT_FILE]
    local name="$1" rc="$2" took="($3 s)" notes="$4" output="${5:-}" line
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
        if [[ -n $output && -s $output ]]; then
            RESULTS+=("         its last lines of output:")
            while IFS= read -r line; do
                RESULTS+=("         | ${line:0:300}")
            done < <(tr -d '\r' <"$output" | tail -n "$FAILED_TAIL_LINES")
        fi
    fi
}

declare -a BG_NAMES=() BG_DIRS=() BG_PIDS=()

step_bg() { # NAME COMMAND [ARGS...]: start the step in the background lane (after the lane's last one)
    local name="$1" dir prev=""
    shift
    dir="$(mktemp -d)"
    ((${#BG_DIRS[@]})) && prev="${BG_DIRS[-1]}"
    echo
    echo "==== [test] $name: started in the background (its output below its header further on) ===="
    (
        if [[ -n $prev ]]; then
            while [[ ! -e $prev/rc ]]; do sleep 1; done
        fi
        t0=$(date +%s)
        : >"$dir/notes"
        ABBE_TEST_NOTES="$dir/notes" "$@" >"$dir/log" 2>&1 </dev/null
        rc=$?
        echo "$(($(date +%s) - t0))" >"$dir/seconds"
        echo "$rc" >"$dir/rc.tmp" && mv "$dir/rc.tmp" "$dir/rc"
    ) &
    BG_NAMES+=("$name")
    BG_DIRS+=("$dir")
    BG_PIDS+=("$!")
}

step_join() { # NAME: wait for the background step, print its log, record its outcome
    local name="$1" i dir rc t_wait=$SECONDS
    for i in "${!BG_NAMES[@]}"; do
        [[ ${BG_NAMES[i]} == "$name" ]] || continue
        dir="${BG_DIRS[i]}"
        wait "${BG_PIDS[i]}"
        echo
        echo "==== [test] $name ===="
        echo "[test] (ran in the background; waited $((SECONDS - t_wait)) s for it here; its output:)"
        cat "$dir/log"
        rc="$(cat "$dir/rc" 2>/dev/null || echo 1)"
        record_step "$name" "$rc" "$(cat "$dir/seconds" 2>/dev/null || echo '?')" "$dir/notes" "$dir/log"
        BG_NAMES[i]="(joined)" # its folder stays until the summary: the next one in the lane looks at rc
        return 0
    done
    echo "[test] step_join: no background step named $name" >&2
    RESULTS+=("FAIL     $name (never started)")
    failed=$((failed + 1))
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
    local n
    for n in "${BG_NAMES[@]}"; do # a background step nobody joined is still waited for and listed
        [[ $n == "(joined)" ]] || step_join "$n"
    done
    # every background step is joined by now; waited for by pid: a bare wait would also wait for
    # the last step's tee (a process substitution), which a process the step left running can hold
    local pid
    for pid in "${BG_PIDS[@]}"; do
        wait "$pid" 2>/dev/null
    done
    ((${#BG_DIRS[@]} == 0)) || rm -rf "${BG_DIRS[@]}"
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

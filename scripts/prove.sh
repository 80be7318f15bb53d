#!/usr/bin/env bash
# The proofs of docs/proofs.md: Frama-C Eva analyses of every reader of
# untrusted bytes and of the evaluators and the compensator on every table
# the loaders accept with a golden table's layout, any scalar fields and
# (3-axis) any coefficients in a box, and on any layout / any thermal block
# within the loaders' invariants (tests/proofs/any_layout.h, thermal_update.c,
# eval_five_any.c: the five-axis kinds, coefficients in a box; and every
# coefficient the loaders accept, through WP-proven contracts: terms_q_l1.c)
# (tests/proofs/*.c), each of which must end with zero alarms and every
# ACSL property it reaches proven (but the hypotheses, which
# tests/proofs/hypotheses.c checks on all their inputs, here); WP's proof of
# the loader contracts (Why3 + Z3); then cppcheck's MISRA C:2012 addon and
# clang-tidy-14 (scripts/prove_lint.sh) when given --lint.
# Fails naming the harness, the function, the place and the alarm.
#   ./scripts/prove.sh [--jobs N] [--only NAME] [--lint] [--open]
# --only NAME: one harness or hypothesis, "wp" (every WP pass) or one WP pass
# as its line names it ("wp terms_q_l1"); a name that is none of these fails.
# --open runs the harnesses that do not hold yet instead (docs/proofs.md, "Not
# proven yet"): they report their alarms and are not part of the pass.
set -uo pipefail

REPO="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
cd "$REPO"
OUT="${ABBE_PROOF_OUT:-$REPO/build-proofs}"
JOBS=2
ONLY=""
LINT=0
OPEN=0
while (($#)); do
    case "$1" in
        --jobs) JOBS="$2"; shift 2 ;;
        --only) ONLY="$2"; shift 2 ;;
        --lint) LINT=1; shift ;;
        --open) OPEN=1; shift ;;
        *) echo "usage: $0 [--jobs N] [--only NAME] [--lint] [--open]" >&2; exit 2 ;;
    esac
done
mkdir -p "$OUT"
command -v frama-c >/dev/null || { echo "[prove] frama-c missing (scripts/setup.sh installs frama-c-base)" >&2; exit 1; }

# Every analysis: the library as compiled for a plain C target (no SIMD, no
# inline assembly: ABBE_PORTABLE_C), both variants, the GCC builtins' contracts.
CPP="-Ilib/include -Ilib/src -DABBE_PORTABLE_C -DABBE_WITH_F32=1 -include tests/proofs/builtins.h"
# Precision only (none of these hides an alarm): partitions per table length
# (//@ split in the harness), the status of check_header kept apart from its
# failures, the loader's call chain analysed state by state.
EVA=(-eva -eva-no-show-progress -eva-print-callstacks -eva-msg-key=-final-states -eva-no-results
     -eva-split-limit 100000)
LOADER_PRECISION="-eva-split-return-function check_header:0 -eva-slevel-function"
# the fixed-point harnesses: a conversion of an integer out of the range of
# the signed type it is converted to ((int32_t) of an int64) is
# implementation-defined, not undefined, and Eva reports it only with this
# option: every _q harness has it (the chain kinds' turned pairs, five_eval_q.c
# rotate_sat_q, are saturated: docs/proofs.md, "Signed downcasts")
DOWNCAST="-warn-signed-downcast"

# name | sources | bound macro | extra options
HARNESSES=(
    "load3|tests/proofs/load3.c lib/src/model_load.c lib/src/crc32.c|-DPROOF_MAX_SIZE=512|$LOADER_PRECISION abbe_model_load:10"
    "load5|tests/proofs/load5.c lib/src/five_load.c lib/src/crc32.c|-DPROOF_MAX_SIZE=512|$LOADER_PRECISION abbe_five_model_load:40"
    # format 1.3: 352 B is the shortest table with a thermal block (256 B of
    # header and axis records, a block of one input and one channel, the CRC)
    "load_thermal|tests/proofs/load_thermal.c lib/src/thermal_load.c lib/src/crc32.c|-DPROOF_MAX_SIZE=352|$LOADER_PRECISION abbe_thermal_load:40"
    "grblhal|tests/proofs/grblhal.c $(ls port/grblhal/src/abbe_grblhal_core*.c lib/src/*.c | tr '\n' ' ')|-Iport/grblhal/include -DPROOF_CHUNK=64|-eva-auto-loop-unroll 16"
    "lcnc_file|tests/proofs/lcnc_file.c port/linuxcnc/src/abbe_lcnc_file.c $(frama-c -print-share-path)/libc/string.c|-Iport/linuxcnc/include -DPROOF_MAX_SIZE=256|"
    "sincos|tests/proofs/sincos.c lib/src/sincos_q.c||$DOWNCAST"
    # the CAN node's frame handling: any sequence of frames of any id, DLC and payload, SYNCs among them
    "can_node|tests/proofs/can_node.c port/socketcan/src/can_node.c port/socketcan/src/can_frame.c port/socketcan/src/can_config_check.c port/socketcan/src/can_status.c $(ls lib/src/*.c | grep -v five_load | tr '\n' ' ')|-Iport/socketcan/include -Iport/socketcan/src|-eva-auto-loop-unroll 16 $DOWNCAST"
)
# the CAN node with a model loaded through its upload path (tests/proofs/can_node.c
# -DPROOF_MODEL): the golden format 1.3 table with any scalars, any SYNC period,
# a SYNC that installs it, then any sequence of frames (the thermal frames
# feeding the thermal runtime, SYNCs running the compensator with the model and
# its thermal state); the load's and the commit's return states kept apart
CAN_NODE_SRCS="tests/proofs/can_node.c tests/golden/golden_thermal.c $(printf 'port/socketcan/src/%s.c ' can_node can_frame can_config_check can_status) $(printf 'lib/src/%s.c ' comp comp_q comp_thermal_q eval_q terms_q terms_sparse_q sincos_q thermal thermal_q model_load thermal_load crc32 status)"
HARNESSES+=("can_node_thermal|$CAN_NODE_SRCS|-Iport/socketcan/include -Iport/socketcan/src -DPROOF_MODEL -DPROOF_CLZ_AS_CODE|-eva-auto-loop-unroll 64 -eva-split-return-function check_header:0,abbe_thermal_load:0,abbe_can_node_commit_model:0,abbe_can_node_load_model:0,abbe_comp_init:0,config_ok:0 -eva-slevel-function abbe_thermal_load:40,abbe_can_node_commit_model:10,abbe_can_node_load_model:10,main:10,abbe_comp_init:10 $DOWNCAST")

# The Modbus register map, one harness per entry point (tests/proofs/modbus.c):
# the port's code as it is, the library's bookkeeping as it is, the calls that
# read a table's content modelled by their documented ranges (modbus_lib.c)
MODBUS_OPTS="-eva-auto-loop-unroll 32 -eva-split-return-function config_ok:0 -eva-slevel-function config_ok:100,abbe_comp_init:10"
MODBUS_SRCS="tests/proofs/modbus.c tests/proofs/modbus_lib.c $(ls port/modbus/src/regs*.c | tr '\n' ' ') lib/src/comp.c lib/src/crc32.c lib/src/thermal.c lib/src/model_load.c"
for e in write upload read; do
    HARNESSES+=("modbus_$e|$MODBUS_SRCS|-Iport/modbus/include -DPROOF_ENTRY_${e^^}|$MODBUS_OPTS")
done

# The evaluations and the compensator's cycles (eval_q.c, eval_f32.c,
# eval_five_q.c, eval_five_f32.c) on the golden tables' layouts
# (tests/golden: every kind the loaders accept: six-term and sparse axes,
# backlash, reversal blocks, thermal, negative travels; the five-axis kinds),
# at every input. __builtin_clz as code (PROOF_CLZ_AS_CODE); the states of the
# loader's and the init's results are kept apart so a refused table or
# configuration does not blur the accepted one.
EVAL_TABLES="paper full sparse negative backlash reversal reversal_sparse"
FIVE_TABLES="ac_full bc_motions ac_location hh_5axiskins ht_maxkins tdr_xyzab ht_maxkins_paper"
# only the sources each harness runs (the parse is about 1 s of CPU per
# harness instead of 2.5 with the whole library); a function reached without
# its source fails the harness ("Neither code nor specification")
EVAL_SRCS="tests/proofs/eval_q.c $(printf 'lib/src/%s.c ' eval_q terms_q terms_sparse_q sincos_q comp comp_q model_load crc32 status)"
EVAL_F32_SRCS="tests/proofs/eval_f32.c $(printf 'lib/src/%s.c ' eval_f32 terms_f32 sincos_f32 comp comp_f32 model_load crc32 status)"
EVAL_OPTS="-eva-auto-loop-unroll 64 -eva-split-return-function check_header:0,abbe_model_load:0,abbe_comp_init:0,config_ok:0 -eva-slevel-function abbe_model_load:10,main:10,abbe_comp_init:10,abbe_comp_step_f32:20"
EVAL_Q_OPTS="${EVAL_OPTS/,abbe_comp_step_f32:20/}" # (no float cycle in the _q harnesses' sources)
golden_tables() { # header source prefix names...: tests/golden's blobs as table_NAME[] and the list
                  # PROOF_TABLES (tests/proofs/tables.h) in $OUT/HEADER
    local header="$OUT/$1" source="$2" prefix="$3" t
    shift 3
    {
        for t in "$@"; do
            sed -n "/^static const uint8_t $prefix$t\[/,/^};/p" "$source" |
                sed "1s/.*/static const unsigned char table_$t[] = {/"
        done
        printf '#define PROOF_TABLES'
        printf ' X(%s)' "$@"
        printf '\n'
    } >"$header.$$"
    for t in "$@"; do
        grep -q "table_$t\[\]" "$header.$$" || { echo "[prove] no golden table $t in $source" >&2; exit 1; }
    done
    mv -f "$header.$$" "$header"
}
# The evaluation and the compensator on every table with the layout of a
# golden table (its version, features, counts, offsets, masks, degrees,
# harmonics, reversal rows) and any scalar field (PROOF_ANY_SCALARS,
# tests/proofs/any_scalars.h) the loader accepts: the real loader runs on
# those bytes. eval_q_<table> / eval_f32_<table>: every coefficient in the
# box of PROOF_ANY_COEFFICIENTS (which holds the coefficients of six of the
# seven golden tables); eval_q_full_golden / eval_f32_full_golden: the full
# table's own coefficients (some beyond the box), any scalars.
ANY="-DPROOF_CLZ_AS_CODE -DPROOF_ANY_SCALARS -I$OUT"
for t in $EVAL_TABLES; do
    golden_tables "tables_$t.h" tests/golden/golden_data.c golden_blob_ "$t"
    HARNESSES+=("eval_q_$t|$EVAL_SRCS|$ANY -DPROOF_ANY_COEFFICIENTS -DPROOF_TABLES_H=tables_$t.h|$EVAL_Q_OPTS $DOWNCAST")
    HARNESSES+=("eval_f32_$t|$EVAL_F32_SRCS|$ANY -DPROOF_ANY_COEFFICIENTS -DPROOF_TABLES_H=tables_$t.h|$EVAL_OPTS")
done
HARNESSES+=("eval_q_full_golden|$EVAL_SRCS|$ANY -DPROOF_TABLES_H=tables_full.h|$EVAL_Q_OPTS $DOWNCAST")
HARNESSES+=("eval_f32_full_golden|$EVAL_F32_SRCS|$ANY -DPROOF_TABLES_H=tables_full.h|$EVAL_OPTS")
# Any layout (tests/proofs/any_layout.h: every term mask, trend degree,
# harmonic count and reversal row count the loader accepts, any scalars):
# terms_q_any proves the fixed-point term kernel's contract
# (tests/proofs/terms_q_contract.h: the term ranges) on every layout, each
# term mask its own partition; eval_q_any_layout runs the evaluation and the
# compensator's cycles on a model of any layout with the kernel as that
# contract (its preconditions checked at each call)
HARNESSES+=("terms_q_any|tests/proofs/terms_q_any.c $(printf 'lib/src/%s.c ' terms_q terms_sparse_q sincos_q)||-eva-auto-loop-unroll 300 -eva-slevel-function terms6_q:100,abbe_axis_terms_sparse_q:100 -eva-slevel-merge-after-loop terms6_q,abbe_axis_terms_sparse_q -eva-interprocedural-splits $DOWNCAST")
HARNESSES+=("eval_q_any_layout|tests/proofs/eval_q_any_layout.c $(printf 'lib/src/%s.c ' eval_q comp comp_q status)||-eva-auto-loop-unroll 300 -eva-use-spec abbe_axis_terms_q -eva-split-return-function abbe_comp_init:0,config_ok:0 -eva-slevel-function main:10,abbe_comp_init:10 $DOWNCAST")
# the float evaluation on any layout, its kernels as they are
HARNESSES+=("eval_f32_any_layout|tests/proofs/eval_f32_any_layout.c $(printf 'lib/src/%s.c ' eval_f32 terms_f32 sincos_f32 status)||-eva-auto-loop-unroll 300 -eva-slevel-function main:10,fold6_body:100,fold6_f32:100,abbe_axis_terms_sparse_f32:100 -eva-slevel-merge-after-loop fold6_body,fold6_f32,abbe_axis_terms_sparse_f32")
# the five-axis evaluations on each five-axis golden table (tests/golden/golden_five.c:
# A/C with every motion, B/C motions, A/C location errors; the head-head,
# head-table and dual rotary table kinds of format 1.4), any scalars of the
# linear axes and of the rotary section (rotation point, offset, squareness,
# location errors), at every joint position
FIVE_SRCS="tests/proofs/eval_five_q.c $(printf 'lib/src/%s.c ' five_eval_q eval_q terms_q terms_sparse_q sincos_q five_load crc32 status)"
FIVE_F32_SRCS="tests/proofs/eval_five_f32.c $(printf 'lib/src/%s.c ' five_eval_f32 eval_f32 terms_f32 terms_rot_f32 sincos_f32 five_load crc32 status)"
FIVE_OPTS="-eva-auto-loop-unroll 64 -eva-split-return-function check_header:0,abbe_five_model_load:0 -eva-slevel-function abbe_five_model_load:40,main:10"
# the float evaluation: the linear part's return states kept apart too (a
# refused input, whose angles are never converted, is not merged with an
# accepted one)
FIVE_F32_OPTS="${FIVE_OPTS/abbe_five_model_load:0/abbe_five_model_load:0,abbe_five_eval_f32_linear:0},abbe_five_eval_f32_linear:10,abbe_five_error_eval_f32:10"
for t in $FIVE_TABLES; do
    golden_tables "tables_five_$t.h" tests/golden/golden_five.c golden_five_ "$t"
    HARNESSES+=("eval_five_q_$t|$FIVE_SRCS|$ANY -DPROOF_TABLES_H=tables_five_$t.h|$FIVE_OPTS $DOWNCAST")
    HARNESSES+=("eval_five_f32_$t|$FIVE_F32_SRCS|$ANY -DPROOF_TABLES_H=tables_five_$t.h|$FIVE_F32_OPTS")
done
# the five-axis evaluations and the compensator's five-axis cycles on a model of
# ANY layout the five-axis loader accepts (tests/proofs/eval_five_any.c: every
# kind, each its own partition; any component mask, harmonics and location
# errors of both rotary records, any geometry within the caps; the linear axes
# as eval_q_any_layout / eval_f32_any_layout), every input
FIVE_ANY_Q_SRCS="tests/proofs/eval_five_any.c $(printf 'lib/src/%s.c ' five_eval_q eval_q sincos_q comp comp_q comp_five comp_five_q status)"
FIVE_ANY_F32_SRCS="tests/proofs/eval_five_any.c $(printf 'lib/src/%s.c ' five_eval_f32 eval_f32 terms_f32 terms_rot_f32 sincos_f32 comp comp_f32 comp_five comp_five_f32 status)"
FIVE_ANY_OPTS="-eva-auto-loop-unroll 300 -eva-split-return-function abbe_comp_init:0,config_ok:0 -eva-interprocedural-splits -eva-slevel-function main:10,abbe_comp_init:10,any5_cycles:10"
HARNESSES+=("eval_five_any_q|$FIVE_ANY_Q_SRCS|-DPROOF_Q|$FIVE_ANY_OPTS,abbe_comp_step5_q:20,motions_q:64 -eva-slevel-merge-after-loop motions_q -eva-use-spec abbe_axis_terms_q $DOWNCAST")
# the same on the loader's whole domain (-DPROOF_ROT_CAPS: every coefficient, the
# tilts and zero offsets within SQUARENESS_CAP): the rotary motions as their
# contract (five_eval_q.c motions_q: checked on the body above, for the box; WP-proven
# for the loader's L1 caps, tests/proofs/terms_q_l1.c rot_trans_q / rot_ang_q)
HARNESSES+=("eval_five_any_q_caps|$FIVE_ANY_Q_SRCS|-DPROOF_Q -DPROOF_ROT_CAPS|$FIVE_ANY_OPTS,abbe_comp_step5_q:20 -eva-use-spec abbe_axis_terms_q,motions_q $DOWNCAST")
FIVE_ANY_F32_OPTS="${FIVE_ANY_OPTS/config_ok:0/config_ok:0,abbe_five_eval_f32_linear:0,eval_f32_linear:full},abbe_five_eval_f32_linear:10,eval_f32_linear:10,abbe_five_error_eval_f32:10,fold6_body:100,fold6_rot_f32:100,fold_values_rot_f32:100,abbe_rotary_motions6_f32:100,motions_sparse_f32:100,abbe_axis_terms_sparse_f32:100 -eva-slevel-merge-after-loop fold6_body,fold6_rot_f32,fold_values_rot_f32,abbe_rotary_motions6_f32,motions_sparse_f32,abbe_axis_terms_sparse_f32"
# the float evaluation and its parts' contracts on the loader's whole domain
# (-DPROOF_ROT_CAPS, as eval_five_any_q_caps: every rotary coefficient, its float
# twin any float within 2^31; the tilts and zero offsets within SQUARENESS_CAP),
# the kernels as they are. (The box version, eval_five_any_f32 without
# PROOF_ROT_CAPS, is not run: the same code, contracts and options on a subset of
# this domain in every field, ROT_LO/ROT_HI, ROT_F_BOX, LIN_F_BOX, LOCATION_BOX,
# nothing else differing: docs/proofs.md, "Cost of the proofs".)
HARNESSES+=("eval_five_any_f32_caps|$FIVE_ANY_F32_SRCS|-DPROOF_NO_COMP -DPROOF_ROT_CAPS|$FIVE_ANY_F32_OPTS")
# the compensator's float five-axis cycle on a model of any layout, the cycles
# only (the evaluation on its own: eval_five_any_f32_caps), on
# the loader's whole domain (-DPROOF_ROT_CAPS: its evaluation's two parts run as
# their contracts, which eval_five_any_f32_caps proves on that domain)
HARNESSES+=("comp_five_any_f32|$FIVE_ANY_F32_SRCS|-DPROOF_COMP_ONLY -DPROOF_ROT_CAPS|$FIVE_ANY_OPTS,abbe_comp_step5_f32:20 -eva-use-spec abbe_five_eval_f32_linear,abbe_five_eval_f32_rotary")
# the float evaluations given any bits, NaN and infinities included: the
# harnesses with -warn-special-float none (a non-finite input is not an alarm
# by itself; every other kind of alarm still counts); the finite harnesses
# above prove that finite inputs give nothing non-finite
HARNESSES+=("eval_five_f32_nonfinite|$FIVE_F32_SRCS|$ANY -DPROOF_TABLES_H=tables_five_ac_full.h -DPROOF_NONFINITE|$FIVE_F32_OPTS -warn-special-float none")
# the five-axis float evaluation on the loader's whole domain (eval_five_any_f32_caps'
# models) given any bits as every position, angle, direction state and temperature
HARNESSES+=("eval_five_any_f32_nonfinite|$FIVE_ANY_F32_SRCS|-DPROOF_NO_COMP -DPROOF_ROT_CAPS -DPROOF_NONFINITE|$FIVE_ANY_F32_OPTS -warn-special-float none")
HARNESSES+=("eval_f32_nonfinite|$EVAL_F32_SRCS|$ANY -DPROOF_TABLES_H=tables_paper.h -DPROOF_NONFINITE|$EVAL_OPTS -warn-special-float none")

# Hypotheses: ACSL assertions in lib/src that Eva cannot decide (a value
# followed through its bits), each checked on all of its 2^32 inputs by
# tests/proofs/hypotheses.c, which this script runs (and fails on); sound
# because the code they run is proven free of undefined behaviour (docs/proofs.md).
# 'sincos_range' (basis_q.h): |sin|, |cos| <= 2^30 from abbe_sincos_q30_pair;
# 'mm_clamped' (internal.h): abbe_mm_clamp_bits gives a finite float in
# [-2147, 2147] for every float; 'f32_finite' (thermal_f32.c): abbe_f32_nonfinite
# is false only for a finite float.
# 'cheb_rows' (basis_q.h) and sincos_range's harmonics: every basis row of the
# _q kernels within 2^30 + 16, the precondition of terms_q_l1.c's WP proof; the
# same harmonics are the five-axis motions' basis (five_eval_q.c motions_q, its
# assertion 'sincos_range').
# 'sincos_norm': sin^2 + cos^2 <= 2^60 + 2^33, the precondition of turn_q.c's WP proof.
HYPOTHESES="sincos_range mm_clamped f32_finite cheb_rows sincos_norm"
# Assertions in lib/src that WP proves on a model (not Eva): may stay unknown to
# Eva; 'turned_w' (five_eval_q.c add_rotary_q): tests/proofs/turn_q.c, its
# preconditions the hypotheses sincos_range, sincos_norm and the assertion
# 'turn_vector' (Eva-proven, every harness)
WP_ASSERTIONS="turned_w"
# the checks run as these groups: one enumeration of the 2^32 phases for both
# sincos_range and sincos_norm (abbe_sincos_q30_pair is most of either's time)
HYPOTHESIS_RUNS=("sincos_range sincos_norm" mm_clamped f32_finite cheb_rows)
check_hypothesis() { # name...: one run of tests/proofs/hypotheses.c, a line a check
    local t0=$SECONDS msg cpu rc timer=()
    rm -f "$OUT/hypotheses.$1.cpu"
    [[ -x /usr/bin/time ]] && timer=(/usr/bin/time -f '%U %S' -o "$OUT/hypotheses.$1.cpu")
    msg=$("${timer[@]}" "$OUT/hypotheses" "$@")
    rc=$?
    cpu=$(awk '/^[0-9.]+ [0-9.]+$/ {printf "%.0f", $1 + $2}' "$OUT/hypotheses.$1.cpu" 2>/dev/null)
    if ((rc != 0)); then
        printf '%s\n' "${msg:-no output (exit $rc)}" | sed 's/^/[prove] FAIL hypothesis /'
        return 1
    fi
    printf '%s\n' "$msg" | sed "s/\$/ ($((SECONDS - t0)) s, ${cpu:-?} s CPU)/; s/^/[prove] ok   hypothesis /"
}

run_one() { # name sources defines options
    local name="$1" srcs="$2" defs="$3" opts="$4" log="$OUT/$1.log"
    local t0=$SECONDS
    # shellcheck disable=SC2086
    local timer=()
    [[ -x /usr/bin/time ]] && timer=(/usr/bin/time -f '%U %S' -o "$OUT/$name.cpu")
    rm -f "$OUT/$name.cpu"
    "${timer[@]}" frama-c -cpp-extra-args="$CPP $defs" $srcs "${EVA[@]}" $opts >"$log" 2>&1
    local rc=$?
    local cpu
    cpu=$(awk '/^[0-9.]+ [0-9.]+$/ {printf "%.0f", $1 + $2}' "$OUT/$name.cpu" 2>/dev/null)
    local secs=$((SECONDS - t0))
    local alarms unknown
    alarms=$(sed -n 's/^ *\([0-9]\+\) alarms\? generated by the analysis.*/\1/p' "$log" | tail -1)
    unknown=$(awk '/^ *(Assertions|Preconditions|Postconditions|Loop invariants|Termination|Function contracts|Behaviors)/ {u += $4; i += $6} END {print u + i + 0}' "$log")
    # Eva's summary does not count a function's postconditions (ensures of a
    # contract it checks at the function's return, tests/proofs/terms_q_contract.h):
    # each one it could not prove is added here
    # (but the loader contracts WP proves, prove_wp below: Eva checks their
    # preconditions at each call, WP the postconditions for all of them)
    unknown=$((unknown + $(grep -c "postcondition '.*' got status \(unknown\|invalid\)" "$log")))
    local wpc
    for wpc in ${WP_CONTRACTS//,/ }; do
        unknown=$((unknown - $(grep -c "postcondition '$wpc' got status unknown" "$log")))
    done
    # the hypotheses' assertions (checked on their own, above) may stay unknown
    local hyp h
    for h in $HYPOTHESES $WP_ASSERTIONS; do
        hyp=$(grep -c "assertion '$h' got status unknown" "$log")
        unknown=$((unknown - hyp))
    done
    local coverage
    coverage=$(sed -n 's/.*functions analyzed (out of [0-9]*): *\([0-9]*%\).*/\1/p' "$log" | tail -1)
    if [[ $rc -ne 0 || -z "$alarms" || "$alarms" != 0 || "$unknown" != 0 ]] || grep -q '^\[kernel\].*[Ee]rror\|User Error\|Neither code nor specification' "$log"; then
        echo "[prove] FAIL $name (${secs} s, ${cpu:-?} s CPU, rc $rc, ${alarms:-?} alarms, $unknown properties not proven): see $log"
        # each alarm: where, what, in which function (the first frame of its call stack)
        # (an assertion's warning has no call stack: printed with its place only, but the
        # hypotheses' and the WP-proven assertions')
        awk -v accepted="$HYPOTHESES $WP_ASSERTIONS" '
             function known(w,    n, h, i) { n = split(accepted, h, " "); for (i = 1; i <= n; i++) if (index(w, "assertion \047" h[i] "\047 got status unknown")) return 1; return 0 }
             function flush() { if (inside && !known(what)) printf "[prove]   %s %s\n", loc, what; inside = 0 }
             /^\[eva:alarm\]/ { flush(); loc = $2; what = ""; inside = 1; next }
             inside && /^\[/ { flush(); next }
             END { flush() }
             inside && /^ *stack: / { fn = $2; if ((getline nxt) > 0 && nxt !~ /^\[/) { split(nxt, c, " "); if (c[2] == "::") fn = fn " (called from " c[1] ")" }
                                      printf "[prove]   %s in %s: %s\n", loc, fn, what; inside = 0; next }
             inside { line = $0; gsub(/^ +/, "", line); what = what (what == "" ? "" : " ") line }' "$log"
        grep -m5 'User Error\|Neither code nor specification\|^\[kernel\].*[Ee]rror' "$log" | sed 's/^/[prove]   /'
        return 1
    fi
    echo "[prove] ok   $name: 0 alarms, every property proven (${secs} s, ${cpu:-?} s CPU; $(grep -o '[0-9]* statements reached (out of [0-9]*): [0-9]*% coverage' "$log" | tail -1))"
}

# the thermal runtime's updates on the golden format 1.3 table
# (tests/golden/golden_thermal.c, loaded from its bytes): init with any period,
# any number of samples of any values, masks and spacings, each followed by
# the application; _f32 with every float bit pattern (NaN and the infinities
# included: -warn-special-float none, every other kind of alarm still counts)
TH_SRCS="tests/proofs/thermal_update.c tests/golden/golden_thermal.c lib/src/thermal_load.c lib/src/thermal.c lib/src/thermal_q.c lib/src/thermal_f32.c lib/src/crc32.c"
TH_OPTS="-eva-auto-loop-unroll 64 -eva-split-return-function check_header:0,abbe_thermal_load:0,abbe_thermal_init_q:0,abbe_thermal_init_f32:0 -eva-slevel-function main:10,abbe_thermal_load:40"
HARNESSES+=(
    "thermal_update_q|$TH_SRCS|-Itests/golden -DPROOF_CLZ_AS_CODE -DPROOF_Q|$TH_OPTS $DOWNCAST"
    "thermal_update_f32|$TH_SRCS|-Itests/golden -DPROOF_CLZ_AS_CODE|$TH_OPTS -warn-special-float none"
)
# the thermal runtime on ANY thermal block the loader accepts (PROOF_ANY_BLOCK,
# tests/proofs/thermal_update.c: the model built within check_thermal's
# invariants, every count of inputs, channels and terms, the inputs the terms
# read, every constant within its cap; or no block), the rest as above
TH_ANY_SRCS="tests/proofs/thermal_update.c lib/src/thermal.c lib/src/thermal_q.c lib/src/thermal_f32.c"
TH_ANY_OPTS="-eva-auto-loop-unroll 64 -eva-split-return-function abbe_thermal_init_q:0,abbe_thermal_init_f32:0 -eva-slevel-function main:10 -eva-interprocedural-splits"
HARNESSES+=(
    "thermal_any_q|$TH_ANY_SRCS|-DPROOF_ANY_BLOCK -DPROOF_Q|$TH_ANY_OPTS $DOWNCAST"
    "thermal_any_f32|$TH_ANY_SRCS|-DPROOF_ANY_BLOCK|$TH_ANY_OPTS -warn-special-float none"
)
# the CAN node's configuration parser: every text of unknown bytes of every
# length 0..64 B
HARNESSES+=("can_config|tests/proofs/can_config.c port/socketcan/src/can_config_parse.c port/socketcan/src/can_toml_number.c port/socketcan/src/can_config_check.c|-Iport/socketcan/include -Iport/socketcan/src -DPROOF_MAX_SIZE=64|-eva-auto-loop-unroll 64 -eva-slevel-function parse_pair:200")
# the compensator with a five-axis model (tests/proofs/comp_five.c): any
# configuration, the table's bytes loaded into a slot and queued
# (abbe_comp_load_five_model; a table of unknown bytes into either slot after
# it), any number of cycles of abbe_comp_step5_q / _f32, resets and swaps among
# them; the trunnion table with every motion (ac_full) and a chain kind
# (tdr_xyzab), any scalars. The load's return states kept apart (a refused and
# an accepted unknown table are not merged)
COMP5_OPTS="-eva-auto-loop-unroll 64 -eva-split-return-function check_header:0,abbe_five_model_load:0,abbe_comp_load_five_model:0,abbe_comp_init:0,config_ok:0 -eva-slevel-function abbe_five_model_load:40,abbe_comp_load_five_model:10,main:10,abbe_comp_init:10,any5_cycles:10"
COMP5_LOAD_MAX=64 # bytes: the table of unknown bytes loaded into a slot (comp_five.c; 512 B does not hold yet: docs/proofs.md, "Not proven yet")
COMP5_SRCS="tests/proofs/comp_five.c $(printf 'lib/src/%s.c ' comp comp_five five_load crc32 status)"
for t in ac_full tdr_xyzab; do # (ht_maxkins: proven once, 21 s of CPU with the load, left out for the CI budget: docs/proofs.md)
    HARNESSES+=("comp_five_q_$t|$COMP5_SRCS $(printf 'lib/src/%s.c ' comp_five_q five_eval_q eval_q terms_q terms_sparse_q sincos_q)|$ANY -DPROOF_Q -DPROOF_LOAD_MAX=$COMP5_LOAD_MAX -DPROOF_TABLES_H=tables_five_$t.h|$COMP5_OPTS $DOWNCAST")
    HARNESSES+=("comp_five_f32_$t|$COMP5_SRCS $(printf 'lib/src/%s.c ' comp_five_f32 comp_f32 five_eval_f32 eval_f32 terms_f32 terms_rot_f32 sincos_f32)|$ANY -DPROOF_LOAD_MAX=$COMP5_LOAD_MAX -DPROOF_TABLES_H=tables_five_$t.h|${COMP5_OPTS/abbe_five_model_load:0/abbe_five_model_load:0,abbe_five_eval_f32_linear:0},abbe_five_eval_f32_linear:10,abbe_comp_step5_f32:20")
done
# the float cycle given any bits (NaN and the infinities included) as every
# position, angle and temperature, as eval_five_f32_nonfinite: -warn-special-float none
HARNESSES+=("comp_five_f32_nonfinite|$COMP5_SRCS $(printf 'lib/src/%s.c ' comp_five_f32 comp_f32 five_eval_f32 eval_f32 terms_f32 terms_rot_f32 sincos_f32)|$ANY -DPROOF_NONFINITE -DPROOF_LOAD_MAX=$COMP5_LOAD_MAX -DPROOF_TABLES_H=tables_five_ac_full.h|${COMP5_OPTS/abbe_five_model_load:0/abbe_five_model_load:0,abbe_five_eval_f32_linear:0},abbe_five_eval_f32_linear:10,abbe_comp_step5_f32:20 -warn-special-float none")
# the L1 proof of the _q term kernels (tests/proofs/terms_q_l1.c): the final
# shifts' postconditions, for every accumulator in range (its WP part: prove_wp)
HARNESSES+=("terms_q_l1_shifts|tests/proofs/terms_q_l1.c|-DPROOF_EVA_SHIFTS|")
HARNESSES+=("turn_q_shift|tests/proofs/turn_q.c|-DPROOF_EVA_SHIFTS|")
# not proven yet: none (docs/proofs.md, "Not proven yet", lists what has no harness)
OPEN_HARNESSES=()
if ((OPEN)); then
    HARNESSES=("${OPEN_HARNESSES[@]}")
fi

# WP: the loader contracts of model_load_checks.h (check_header, array_ok;
# compiled through model_load.c, which includes it; and check_counts with its
# helpers, lib/src/model_load_acsl.h), proven
# by Z3 through Why3 (Debian 12: why3 1.5.1, z3 4.8.12; Alt-Ergo is not
# packaged). Why3's prover list is written into $OUT, not the home directory.
WP_CONTRACTS="accepted_total,inside"
WP_RAN=0
wp_run() { # NAME WHAT LOG FRAMA-C-ARGS...: one WP pass, all its goals proven or a failure naming them
    local name="$1" what="$2" log="$3" t0=$SECONDS proved
    shift 3
    # --only wp: every WP pass; --only "wp NAME": that one (as its [prove] line names it)
    [[ -z "$ONLY" || "$ONLY" == wp || "$ONLY" == "$name" ]] || return 0
    WP_RAN=$((WP_RAN + 1))
    # CPU: frama-c's and its provers' (Why3's server and the Z3 runs it waits for)
    local timer=() cpu
    rm -f "$log.cpu"
    [[ -x /usr/bin/time ]] && timer=(/usr/bin/time -f '%U %S' -o "$log.cpu")
    "${timer[@]}" frama-c "$@" >"$log" 2>&1
    cpu=$(awk '/^[0-9.]+ [0-9.]+$/ {printf "%.0f", $1 + $2}' "$log.cpu" 2>/dev/null)
    proved=$(sed -n 's/.*Proved goals: *\([0-9]*\) \/ \([0-9]*\).*/\1 \2/p' "$log" | tail -1)
    if [[ -z "$proved" || "${proved% *}" != "${proved#* }" || "${proved% *}" == 0 ]]; then
        local shown="${proved/ / of }"
        echo "[prove] FAIL $name: ${shown:-no} goals proven ($what): see $log"
        grep -A1 'Goal.*\(Failed\|Unknown\|Timeout\)\|\[\(Failed\|Unknown\|Timeout\)\] Goal' "$log" | sed 's/^/[prove]   /'
        return 1
    fi
    echo "[prove] ok   $name: ${proved% *} of ${proved#* } goals proven ($what; $((SECONDS - t0)) s, ${cpu:-?} s CPU)"
}

prove_wp() {
    command -v why3 >/dev/null && command -v z3 >/dev/null && command -v cvc4 >/dev/null ||
        { echo "[prove] FAIL wp: why3, z3 or cvc4 missing (scripts/setup.sh installs them)"; return 1; }
    export WHY3CONFIG="$OUT/why3.conf"
    # (detected again if a configuration written before CVC4 was installed lacks it)
    [[ -s "$WHY3CONFIG" ]] && grep -q CVC4 "$WHY3CONFIG" || why3 config detect >/dev/null 2>&1
    wp_run wp "$WP_CONTRACTS" "$OUT/wp.log" -cpp-extra-args="$CPP" lib/src/model_load.c -wp \
        -wp-fct check_header,array_ok -wp-prop "$WP_CONTRACTS" -wp-prover z3 -wp-timeout 30 || return 1
    # the 3-axis loader's count contracts (lib/src/model_load_acsl.h, seen only
    # with ABBE_PROOF_WP: no compiler, no Eva harness reads them): check_counts
    # accepts only records within table_counts_ok, with popcount6,
    # trend_rows_of, n_basis_of, bit_length and every loop invariant; all goals
    # of these functions. wp:range / wp:split: WP's case split on the axis
    # index (Z3 alone does not relate the record at 64 + 64 j to j); Z3 needs
    # about 2 s on the hardest goal, more under load, hence the 200 s bound
    wp_run "wp loader" "check_counts' counts_ok and its helpers" "$OUT/wp_loader.log" \
        -cpp-extra-args="$CPP -DABBE_PROOF_WP" lib/src/model_load.c -wp \
        -wp-fct popcount6,trend_rows_of,n_basis_of,bit_length,check_counts \
        -wp-prover z3 -wp-timeout 200 -wp-auto wp:range,wp:split || return 1
    # the five-axis loader's rotary records (lib/src/model_load_rotary_acsl.h, seen
    # only with ABBE_PROOF_WP): check_rotary accepts only records within
    # rotary_table_counts_ok, build_rotary makes of such a record a model within
    # rotary_layout_ok (its ranges and location errors: the predicates
    # tests/proofs/eval_five_any.c asserts of its records), with every helper they
    # call; all goals of these functions. Z3, then CVC4 on a goal Z3 does not prove:
    # layout_ok (Z3 fails it since the location errors are in it; CVC4 1.8 proves it
    # in ~2 s, ~0.2 M steps; the pass ~+7 s of CPU). Bounded by steps: the goals Z3
    # proves take at most 8.1 M; Z3's failing attempt on layout_ok ran to the 200 s
    # wall-clock bound on an idle machine (149 s of CPU for the pass), 20 M steps
    # stop it at the same point at any load (58 s)
    # (coef_word is used here through its contract: its postcondition `word` needs
    # abbe_ld_u32's value, seen only in the `wp l1 caps` pass, which proves it; the
    # same function of model_load_checks.h, included by both loaders)
    local ROT_FCTS="rotary_record,any_nonzero_u8,any_above,hh_lever_too_long,mag_i32,abbe_f32_bits_nonfinite,rotary_record_bad,check_rotary,capped_i32,others_of,geometry_at,angle_at,build_rotary"
    wp_run "wp five loader" "check_rotary's counts_ok, build_rotary's layout_ok with the location errors, and their helpers" \
        "$OUT/wp_five_loader.log" -cpp-extra-args="$CPP -DABBE_PROOF_WP" lib/src/five_load.c -wp \
        -wp-fct "$ROT_FCTS" -wp-prover z3,cvc4 -wp-steps 20000000 -wp-timeout 200 -wp-auto wp:range,wp:split || return 1
    # build_axis' contract (model_load_acsl.h, with ABBE_PROOF_WP): the model it
    # makes of a record within record_counts_ok satisfies axis_layout_ok (which
    # implies the term kernels' precondition axis_ranges_ok); all goals of
    # build_axis (no case split needed). layout_ok is the hardest goal: about
    # 30 s of Z3's CPU (27-30 M steps). Z3's -T bound is wall-clock time (at a
    # load average of ~25 the goal failed at 300 s, reported "Unknown error"):
    # bounded by steps instead (-wp-steps: the same result at any load), with a
    # wall-clock bound that only stops a hang
    wp_run "wp build_axis" "build_axis' layout_ok" "$OUT/wp_build_axis.log" \
        -cpp-extra-args="$CPP -DABBE_PROOF_WP" lib/src/model_load.c -wp -wp-fct build_axis \
        -wp-prover z3 -wp-steps 60000000 -wp-timeout 900 || return 1
    # the thermal block loader (lib/src/thermal_acsl.h, seen only with
    # ABBE_PROOF_WP): check_thermal accepts only blocks within thermal_block_ok
    # (P: block_ok and every loop invariant), with its reads th_u8 / th_u16 /
    # th_u32 / th_i32 (the table's value at an offset inside [0, total - 4) or 0,
    # as the logic readers P is written with), th_input / th_channel / th_term
    # (the records' offsets), th_abs_over, th_cap; all goals of these functions.
    # CVC4: Z3 4.8.12 (through Why3 1.5.1) fails the quantified prefix invariants
    # ("Unknown error"). Bounded by steps (CVC4's resource limit: the hardest goal
    # takes about 79 000), the wall-clock bound only stops a hang. build_thermal's
    # model_ok is stated there, not proven yet (docs/proofs.md, "WP: the thermal loader")
    wp_run "wp thermal" "check_thermal's block_ok, the thermal loader's reads and offsets" "$OUT/wp_thermal.log" \
        -cpp-extra-args="$CPP -DABBE_PROOF_WP" lib/src/thermal_load.c -wp \
        -wp-fct th_input,th_channel,th_term,th_u8,th_u16,th_u32,th_i32,th_abs_over,th_cap,check_thermal \
        -wp-prover cvc4 -wp-steps 1000000 -wp-timeout 600 || return 1
    # the 3-axis loader's L1 caps (lib/src/model_load_acsl.h, ABBE_PROOF_WP only):
    # check_ranges accepts only tables whose every present term keeps sum |c|
    # (column_l1, the sum over the term's words as the code reads them) within
    # LIN_L1_CAP / ANG_L1_CAP on each axis (l1_caps), with column_l1_of's
    # loop (the uint64 sum never wraps), coef_word, abs_i32 and mag_i32; all
    # goals of these four functions (wp:range / wp:split: the axis and term
    # indices, as for check_counts); check_ranges' squareness_caps and
    # reversal_caps from its two callees' contracts, proven in `wp caps` below.
    # Z3 does not prove one goal directly (the strategies then do): bounded by
    # steps, not only by the 60 s wall-clock bound, so the failing attempt costs
    # the same at any load (the goals Z3 proves take at most 4.3 M steps)
    wp_run "wp l1 caps" "check_ranges' l1_caps and its helpers" "$OUT/wp_l1_caps.log" \
        -cpp-extra-args="$CPP -DABBE_PROOF_WP -DABBE_PROOF_WP_L1" lib/src/model_load.c -wp \
        -wp-fct coef_word,abs_i32,column_l1_of,check_ranges \
        -wp-prover z3 -wp-steps 20000000 -wp-timeout 60 -wp-auto wp:range,wp:split || return 1
    # check_ranges' other caps (model_load_acsl.h, ABBE_PROOF_WP only):
    # check_squareness accepts only a header whose three squareness words are
    # within SQUARENESS_CAP (squareness_caps), check_reversal only axes with
    # |B| + sum |r_k| <= REVERSAL_L1_CAP (reversal_caps: reversal_l1, the sum
    # over the rows after the matrix as the code reads them), with mag_i32; all
    # goals. Bounded by Z3's steps (the same outcome at any load), the
    # wall-clock bound only stops a hang
    wp_run "wp caps" "check_squareness' squareness_caps, check_reversal's reversal_caps" \
        "$OUT/wp_caps.log" -cpp-extra-args="$CPP -DABBE_PROOF_WP -DABBE_PROOF_WP_L1" lib/src/model_load.c -wp \
        -wp-fct mag_i32,check_squareness,check_reversal \
        -wp-prover z3 -wp-steps 20000000 -wp-timeout 600 -wp-auto wp:range,wp:split || return 1
    # the _q term kernels' and the five-axis rotary motions' (motions_q) accumulation
    # under the loader's L1 caps and the basis rows' bound (tests/proofs/terms_q_l1.c;
    # the shifts: Eva, above)
    # (the model's functions only: the file includes the loader's caps, model_load_layout.h)
    local L1_FCTS="row_product,term_acc,term_lin_q,term_ang_q,rot_trans_q,rot_ang_q,lin_high_word,ang_shifted,rot_trans_shifted,rot_ang_shifted"
    L1_FCTS+=",term_lin_q_table,term_ang_q_table" # the kernels' cap in the loader's column_l1 (l1_caps above)
    wp_run "wp terms_q_l1" "the L1 accumulation" "$OUT/wp_terms_q_l1.log" \
        -cpp-extra-args="$CPP" tests/proofs/terms_q_l1.c -wp -wp-fct "$L1_FCTS" -wp-rte \
        -wp-prop="-lin_shift,-ang_shift,-rot_trans_shift,-rot_ang_shift" -wp-prover z3 -wp-timeout 30 || return 1
    # the trunnion table axis' angle sum turned by the tilt (tests/proofs/turn_q.c:
    # five_eval_q.c's assertion 'turned_w'; the shift: Eva, turn_q_shift)
    wp_run "wp turn_q" "the turned angle sum" "$OUT/wp_turn_q.log" \
        tests/proofs/turn_q.c -wp -wp-rte -wp-prop=-turned_shift -wp-prover z3 -wp-timeout 30
}

pids=()
names=()
fail=0
if ((!OPEN)) && [[ -z "$ONLY" || "$ONLY" == wp || "$ONLY" == "wp "* ]]; then
    { prove_wp || exit 1
      ((WP_RAN)) || { echo "[prove] FAIL --only $ONLY: no WP pass of that name"; exit 1; }; } &
    pids+=($!)
fi
if ((!OPEN)); then
    # -O3 -march=native: the basis rows' checks vectorized (built and run here)
    cc -std=c99 -O3 -march=native -Ilib/include -Ilib/src -DABBE_PORTABLE_C tests/proofs/hypotheses.c lib/src/sincos_q.c \
        -o "$OUT/hypotheses" || { echo "[prove] FAIL tests/proofs/hypotheses.c does not compile"; exit 1; }
    for h in "${HYPOTHESIS_RUNS[@]}"; do
        [[ -n "$ONLY" && " $h " != *" $ONLY "* ]] && continue
        [[ -n "$ONLY" ]] && h="$ONLY"
        while (($(jobs -rp | wc -l) >= JOBS)); do wait -n || fail=1; done
        check_hypothesis $h &
        pids+=($!)
    done
fi
if [[ -n "$ONLY" && "$ONLY" != wp && "$ONLY" != "wp "* && " $HYPOTHESES " != *" $ONLY "* ]] &&
    ! printf '%s\n' "${HARNESSES[@]}" | grep -q "^$ONLY|"; then
    echo "[prove] FAIL --only $ONLY: no harness, hypothesis or WP pass of that name"
    fail=1
fi
for h in "${HARNESSES[@]}"; do
    IFS='|' read -r name srcs defs opts <<<"$h"
    [[ -n "$ONLY" && "$ONLY" != "$name" ]] && continue
    while (($(jobs -rp | wc -l) >= JOBS)); do wait -n || fail=1; done
    run_one "$name" "$srcs" "$defs" "$opts" &
    pids+=($!)
done
# every job's status, by its pid: a job that ended while none was waited for
# (jobs -rp no longer lists it) is not lost
for p in "${pids[@]}"; do wait "$p" || fail=1; done

if ((LINT)); then
    "$REPO/scripts/prove_lint.sh" || fail=1
fi
if ((fail)); then
    echo "[prove] FAILED"
    exit 1
fi
echo "[prove] all proofs hold"

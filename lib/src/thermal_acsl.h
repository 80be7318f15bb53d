/* abbe: the thermal block's invariants as ACSL predicates (comments only: no
 * code), one statement meant for
 *  - the loader's contracts (thermal_load.c):
 *      check_thermal(b, total) == ABBE_OK  ->  thermal_block_ok(b, total)   (P)
 *      thermal_block_ok(b, total)          ->  build_thermal makes a model
 *                                              with thermal_model_ok(th)    (Q)
 *    the first step PROVEN: WP (CVC4 1.8 through Why3 1.5.1) proves
 *    check_thermal's block_ok, every loop invariant and the helpers'
 *    contracts (th_u8 .. th_cap: scripts/prove.sh, "wp thermal"); the second,
 *    build_thermal's model_ok, is STATED, NOT PROVEN YET (docs/proofs.md, "WP:
 *    the thermal loader", what fails and why);
 *  - the runtime's proofs on any block (tests/proofs/thermal_update.c,
 *    PROOF_ANY_BLOCK: thermal_any_q, thermal_any_f32), whose model draws each
 *    field over the range thermal_model_ok allows (a superset of it: vmin <
 *    vmax and distinct outputs not imposed).
 * Not installed. */
#ifndef ABBE_THERMAL_ACSL_H
#define ABBE_THERMAL_ACSL_H

#include "abbe/thermal.h"

/* "P (or Q) holds for every index below n" is a \forall over the index (a
 * prefix predicate): CVC4 1.8 proves its loop invariants; Z3 4.8.12 through
 * Why3 1.5.1 fails them, and a version spelt out over the fixed sizes (17
 * inputs, 5 channels, 4 terms) was not proven by either (docs/proofs.md). */

/* ---- Q: the model the runtime may be given ---------------------------- */

/* input k: kind, reference, valid range, step, stuck time and resolution
 * (the ranges: value cap 2^20, step cap 2^21 milli-units; stuck time whole
 * minutes 0..255, resolution 0..65535, 0 without a stuck time) */
/*@ predicate th_model_input_ranges(abbe_thermal_model_t *th, integer k) =
        th->kind[k] <= ABBE_THERMAL_SPEED &&
        -1048576 <= th->ref_milli[k] <= 1048576 &&
        -1048576 <= th->vmin_milli[k] <= 1048576 &&
        -1048576 <= th->vmax_milli[k] <= 1048576 &&
        1 <= th->max_step_milli[k] <= 2097152 &&
        th->stuck_ms[k] <= 15300000 && th->stuck_ms[k] % 60000 == 0 &&
        0 <= th->stuck_res_milli[k] <= 65535 &&
        (th->stuck_ms[k] == 0 ==> th->stuck_res_milli[k] == 0);
    predicate th_model_input_ok(abbe_thermal_model_t *th, integer k) =
        th_model_input_ranges(th, k) && th->vmin_milli[k] < th->vmax_milli[k];
 */
/* term k of channel c: the input it reads, time constant 0..2^31 ms,
 * |gain| <= 2^28 */
/*@ predicate th_model_term_ok(abbe_thermal_model_t *th, integer c, integer k) =
        th->term_input[c][k] < th->n_inputs &&
        th->tau_ms[c][k] <= 2147483648 &&
        -268435456 <= th->gain_q16[c][k] <= 268435456;
 */
/* channel c: its output, 1..4 terms, limit 1..2^30 */
/*@ predicate th_model_channel_ok(abbe_thermal_model_t *th, integer c) =
        th->output[c] <= ABBE_THERMAL_OUT_B &&
        1 <= th->n_terms[c] <= ABBE_THERMAL_MAX_TERMS &&
        1 <= th->limit[c] <= 1073741824 &&
        \forall integer k; 0 <= k < th->n_terms[c] ==> th_model_term_ok(th, c, k);
    predicate th_model_channels_below(abbe_thermal_model_t *th, integer n) =
        \forall integer c; 0 <= c < n ==> th_model_channel_ok(th, c);
 */
/* the inputs below n, the channels below n, channel c's terms below n */
/*@ predicate th_model_terms_below(abbe_thermal_model_t *th, integer c, integer n) =
        \forall integer k; 0 <= k < n ==> th_model_term_ok(th, c, k);
    predicate th_model_inputs_below(abbe_thermal_model_t *th, integer n) =
        \forall integer k; 0 <= k < n ==> th_model_input_ok(th, k);
    predicate th_model_input_ranges_below(abbe_thermal_model_t *th, integer n) =
        \forall integer k; 0 <= k < n ==> th_model_input_ranges(th, k);
 */
/* a block's counts and times */
/*@ predicate th_model_counts_ok(abbe_thermal_model_t *th) =
        1 <= th->n_inputs <= ABBE_THERMAL_MAX_INPUTS &&
        1 <= th->n_channels <= ABBE_THERMAL_MAX_CHANNELS &&
        1 <= th->max_gap_ms <= 2147483648 && 1 <= th->fade_ms <= 2147483648;
 */
/* Q: no block at all (0 inputs, 0 channels), or a block within the caps;
 * the tool offset t_z is any int32; channel_inputs[c] and the float twins
 * are computed from these fields (the same expressions in build_thermal and
 * in the harness), so they are not stated. Distinct channel outputs: not
 * stated (check_thermal refuses a repeated output with a bit mask; the
 * runtime does not need it: a superset) */
/*@ predicate thermal_model_ok(abbe_thermal_model_t *th) =
        (th->n_inputs == 0 && th->n_channels == 0) ||
        (th_model_counts_ok(th) && th_model_inputs_below(th, th->n_inputs) &&
         th_model_channels_below(th, th->n_channels));
 */
/* Q less vmin < vmax: the part an interval analysis (Eva) checks on the
 * harness' models (which do not impose vmin < vmax: a superset of Q) */
/*@ predicate thermal_model_ranges_ok(abbe_thermal_model_t *th) =
        (th->n_inputs == 0 && th->n_channels == 0) ||
        (th_model_counts_ok(th) && th_model_input_ranges_below(th, th->n_inputs) &&
         th_model_channels_below(th, th->n_channels));
 */

/* ---- P: the bytes of a block check_thermal accepts ---------------------- */

/* The loads of internal.h as functions of their bytes, uninterpreted: the
 * contracts below say only that a load's value is a function of the bytes
 * it reads (assumed, not proven: abbe_ld_i32 reinterprets through memcpy,
 * which the Typed model does not follow), which is all the chain needs:
 * build_thermal reads the values check_thermal checked */
/*@ axiomatic th_loads {
      logic integer u16_of_bytes(integer b0, integer b1);
      logic integer u32_of_bytes(integer b0, integer b1, integer b2, integer b3);
      logic integer i32_of_bytes(integer b0, integer b1, integer b2, integer b3);
    }
 */
/* thermal_load.c's bounded reads th_u8, th_u16, th_u32, th_i32 */
/*@ logic integer th_u8_l(uint8_t *b, integer total, integer at) =
        total >= 5 && at < total - 4 ? b[at] : 0;
    logic integer th_u16_l(uint8_t *b, integer total, integer at) =
        total >= 6 && at <= total - 6 ? u16_of_bytes(b[at], b[at + 1]) : 0;
    logic integer th_u32_l(uint8_t *b, integer total, integer at) =
        total >= 8 && at <= total - 8 ? u32_of_bytes(b[at], b[at + 1], b[at + 2], b[at + 3]) : 0;
    logic integer th_i32_l(uint8_t *b, integer total, integer at) =
        total >= 8 && at <= total - 8 ? i32_of_bytes(b[at], b[at + 1], b[at + 2], b[at + 3]) : 0;
 */
/* the block's offset (the header's reserved word, byte 60), its counts, its
 * records' offsets (docs/table-format.md, "Thermal block") */
/*@ logic integer th_t(uint8_t *b) = u32_of_bytes(b[60], b[61], b[62], b[63]);
    logic integer th_nin(uint8_t *b, integer total) = th_u8_l(b, total, th_t(b));
    logic integer th_nch(uint8_t *b, integer total) = th_u8_l(b, total, th_t(b) + 1);
    logic integer th_in_at(uint8_t *b, integer k) = th_t(b) + 16 + 20 * k;
    logic integer th_ch_at(uint8_t *b, integer total, integer c) = th_t(b) + 16 + 20 * th_nin(b, total) + 56 * c;
    logic integer th_tm_at(integer ch, integer k) = ch + 8 + 12 * k;
 */
/* OFFSET and COUNT of the block: aligned, after the axis records, inside
 * [t, total - 4) with its 1..17 inputs and 1..5 channels */
/*@ predicate th_block_offsets_ok(uint8_t *b, integer total) =
        (th_t(b) & 3) == 0 && 256 <= th_t(b) && th_t(b) <= total - 4 &&
        1 <= th_nin(b, total) <= ABBE_THERMAL_MAX_INPUTS &&
        1 <= th_nch(b, total) <= ABBE_THERMAL_MAX_CHANNELS &&
        total - 4 - th_t(b) >= 16 + 20 * th_nin(b, total) + 56 * th_nch(b, total);
 */
/* input k's FLAGS (kind; no resolution without a stuck time) */
/*@ predicate th_block_input_flags(uint8_t *b, integer total, integer k) =
        th_u8_l(b, total, th_in_at(b, k)) <= ABBE_THERMAL_SPEED &&
        (th_u8_l(b, total, th_in_at(b, k) + 1) == 0 ==> th_u16_l(b, total, th_in_at(b, k) + 2) == 0);
 */
/* input k's RANGE (reference, valid min < valid max, step) */
/*@ predicate th_block_input_range(uint8_t *b, integer total, integer k) =
        -1048576 <= th_i32_l(b, total, th_in_at(b, k) + 4) <= 1048576 &&
        -1048576 <= th_i32_l(b, total, th_in_at(b, k) + 8) <= 1048576 &&
        -1048576 <= th_i32_l(b, total, th_in_at(b, k) + 12) <= 1048576 &&
        th_i32_l(b, total, th_in_at(b, k) + 8) < th_i32_l(b, total, th_in_at(b, k) + 12) &&
        1 <= th_i32_l(b, total, th_in_at(b, k) + 16) <= 2097152;
 */
/* channel c's COUNT of terms, and the inputs its terms read */
/*@ logic integer th_nterms(uint8_t *b, integer total, integer c) = th_u8_l(b, total, th_ch_at(b, total, c) + 1);
    predicate th_block_term_input(uint8_t *b, integer total, integer c, integer k) =
        th_u8_l(b, total, th_tm_at(th_ch_at(b, total, c), k)) < th_nin(b, total);
    predicate th_block_term_inputs_below(uint8_t *b, integer total, integer c, integer n) =
        \forall integer k; 0 <= k < n ==> th_block_term_input(b, total, c, k);
    predicate th_block_channel_count(uint8_t *b, integer total, integer c) =
        1 <= th_nterms(b, total, c) <= ABBE_THERMAL_MAX_TERMS &&
        th_block_term_inputs_below(b, total, c, th_nterms(b, total, c));
 */
/* channel c's output (FLAGS) and RANGE (limit; per term, tau and gain) */
/*@ predicate th_block_term_range(uint8_t *b, integer total, integer c, integer k) =
        th_u32_l(b, total, th_tm_at(th_ch_at(b, total, c), k) + 4) <= 2147483648 &&
        -268435456 <= th_i32_l(b, total, th_tm_at(th_ch_at(b, total, c), k) + 8) <= 268435456;
    predicate th_block_term_ranges_below(uint8_t *b, integer total, integer c, integer n) =
        \forall integer k; 0 <= k < n ==> th_block_term_range(b, total, c, k);
    predicate th_block_channel_range(uint8_t *b, integer total, integer c) =
        1 <= th_i32_l(b, total, th_ch_at(b, total, c) + 4) <= 1073741824 &&
        th_block_term_ranges_below(b, total, c, th_nterms(b, total, c));
    predicate th_block_channel_output(uint8_t *b, integer total, integer c) =
        th_u8_l(b, total, th_ch_at(b, total, c)) <= ABBE_THERMAL_OUT_B;
 */
/* the inputs and channels below n */
/*@ predicate th_block_in_flags_below(uint8_t *b, integer total, integer n) =
        \forall integer k; 0 <= k < n ==> th_block_input_flags(b, total, k);
    predicate th_block_in_ranges_below(uint8_t *b, integer total, integer n) =
        \forall integer k; 0 <= k < n ==> th_block_input_range(b, total, k);
    predicate th_block_outputs_below(uint8_t *b, integer total, integer n) =
        \forall integer c; 0 <= c < n ==> th_block_channel_output(b, total, c);
    predicate th_block_counts_below(uint8_t *b, integer total, integer n) =
        \forall integer c; 0 <= c < n ==> th_block_channel_count(b, total, c);
    predicate th_block_ch_ranges_below(uint8_t *b, integer total, integer n) =
        \forall integer c; 0 <= c < n ==> th_block_channel_range(b, total, c);
 */
/* P: a block check_thermal accepts. Not stated: the reserved bytes and the
 * unused term slots being 0 and the outputs being distinct (FLAGS checks no
 * reader relies on) */
/*@ predicate thermal_block_ok(uint8_t *b, integer total) =
        th_block_offsets_ok(b, total) &&
        1 <= th_u32_l(b, total, th_t(b) + 4) <= 2147483648 &&
        1 <= th_u32_l(b, total, th_t(b) + 8) <= 2147483648 &&
        th_block_in_flags_below(b, total, th_nin(b, total)) &&
        th_block_in_ranges_below(b, total, th_nin(b, total)) &&
        th_block_outputs_below(b, total, th_nch(b, total)) &&
        th_block_counts_below(b, total, th_nch(b, total)) &&
        th_block_ch_ranges_below(b, total, th_nch(b, total));
 */

/* The loops' annotations of those contracts (TH_LOOP_*, in thermal_load.c's
 * loops): the invariants under ABBE_PROOF_WP, a trivial one in the other
 * Frama-C runs (an annotation cannot be empty: the Eva harnesses see the
 * loops as before); nothing at all for a compiler or cppcheck. */
#if defined(ABBE_PROOF_WP)
/* the block inside the table, no offset wrapping (check_thermal: after its
 * OFFSET check; build_thermal: from thermal_block_ok) */
#define TH_ASSERT_FITS                                                                     \
    assert th_fits: t + 16 + 20 * n_in + 56 * n_ch <= total - 4 && t == th_t(b) &&         \
        n_in == th_nin(b, total) && n_ch == th_nch(b, total);
/* check_thermal: the block's times as P reads them; channel c's term count,
 * checked by the COUNT loop (th_counts), where the RANGE loop reads it */
#define TH_ASSERT_TIMES                                                                    \
    assert th_times: gap == th_u32_l(b, total, th_t(b) + 4) && fade == th_u32_l(b, total, th_t(b) + 8);
#define TH_ASSERT_COUNTED                                                                  \
    assert th_counted: n_terms == th_nterms(b, total, c) && th_block_channel_count(b, total, c);
/* check_thermal */
#define TH_LOOP_IN_FLAGS                                                                   \
    loop invariant th_in_flags: 0 <= k <= n_in &&                                          \
        th_block_in_flags_below(b, total, k);              \
    loop assigns k;                                                                        \
    loop variant n_in - k;
#define TH_LOOP_CH_FLAGS                                                                   \
    loop invariant th_outputs: 0 <= c <= n_ch &&                                           \
        th_block_outputs_below(b, total, c);           \
    loop assigns c, outputs;                                                               \
    loop variant n_ch - c;
#define TH_LOOP_SLOTS                                                                      \
    loop invariant th_slots: 0 <= k <= ABBE_THERMAL_MAX_TERMS;                             \
    loop assigns k;                                                                        \
    loop variant ABBE_THERMAL_MAX_TERMS - k;
#define TH_LOOP_CH_COUNT                                                                   \
    loop invariant th_counts: 0 <= c <= n_ch &&                                            \
        th_block_counts_below(b, total, c);            \
    loop assigns c;                                                                        \
    loop variant n_ch - c;
#define TH_LOOP_TERM_INPUT                                                                 \
    loop invariant th_term_inputs: 0 <= k <= n_terms &&                                    \
        th_block_term_inputs_below(b, total, c, k);            \
    loop assigns k;                                                                        \
    loop variant n_terms - k;
#define TH_LOOP_IN_RANGE                                                                   \
    loop invariant th_in_ranges: 0 <= k <= n_in &&                                         \
        th_block_in_ranges_below(b, total, k);              \
    loop assigns k;                                                                        \
    loop variant n_in - k;
#define TH_LOOP_CH_RANGE                                                                   \
    loop invariant th_ch_ranges: 0 <= c <= n_ch &&                                         \
        th_block_ch_ranges_below(b, total, c);            \
    loop assigns c;                                                                        \
    loop variant n_ch - c;
#define TH_LOOP_TERM_RANGE                                                                 \
    loop invariant th_term_ranges: 0 <= k <= n_terms &&                                    \
        th_block_term_ranges_below(b, total, c, k);            \
    loop assigns k;                                                                        \
    loop variant n_terms - k;
/* build_thermal */
#define TH_LOOP_BUILD_INPUTS                                                               \
    loop invariant th_inputs_built: 0 <= k <= n_in &&                                      \
        th_model_inputs_below(th, k);                       \
    loop assigns k, th->kind[0 .. ABBE_THERMAL_MAX_INPUTS - 1],                            \
        th->ref_milli[0 .. ABBE_THERMAL_MAX_INPUTS - 1],                                   \
        th->vmin_milli[0 .. ABBE_THERMAL_MAX_INPUTS - 1],                                  \
        th->vmax_milli[0 .. ABBE_THERMAL_MAX_INPUTS - 1],                                  \
        th->max_step_milli[0 .. ABBE_THERMAL_MAX_INPUTS - 1],                              \
        th->stuck_ms[0 .. ABBE_THERMAL_MAX_INPUTS - 1],                                    \
        th->stuck_res_milli[0 .. ABBE_THERMAL_MAX_INPUTS - 1];                             \
    loop variant n_in - k;
#define TH_LOOP_BUILD_CHANNELS                                                             \
    loop invariant th_channels_built: 0 <= c <= n_ch &&                                    \
        th_model_channels_below(th, c);                     \
    loop invariant th_inputs_kept: th_model_inputs_below(th, n_in); \
    loop assigns c, th->output[0 .. ABBE_THERMAL_MAX_CHANNELS - 1],                        \
        th->n_terms[0 .. ABBE_THERMAL_MAX_CHANNELS - 1],                                   \
        th->limit[0 .. ABBE_THERMAL_MAX_CHANNELS - 1],                                     \
        th->term_input[0 .. ABBE_THERMAL_MAX_CHANNELS - 1][0 .. ABBE_THERMAL_MAX_TERMS - 1], \
        th->channel_inputs[0 .. ABBE_THERMAL_MAX_CHANNELS - 1],                            \
        th->tau_ms[0 .. ABBE_THERMAL_MAX_CHANNELS - 1][0 .. ABBE_THERMAL_MAX_TERMS - 1],   \
        th->gain_q16[0 .. ABBE_THERMAL_MAX_CHANNELS - 1][0 .. ABBE_THERMAL_MAX_TERMS - 1]; \
    loop variant n_ch - c;
#define TH_LOOP_BUILD_TERMS                                                                \
    loop invariant th_terms_built: 0 <= k <= n_terms &&                                    \
        th_model_terms_below(th, c, k);                     \
    loop assigns k, th->term_input[c][0 .. ABBE_THERMAL_MAX_TERMS - 1],                    \
        th->channel_inputs[c], th->tau_ms[c][0 .. ABBE_THERMAL_MAX_TERMS - 1],             \
        th->gain_q16[c][0 .. ABBE_THERMAL_MAX_TERMS - 1];                                  \
    loop variant n_terms - k;
#define TH_LOOP_TWINS_INPUTS                                                               \
    loop invariant th_twins_in: 0 <= k <= n_in;                                            \
    loop assigns k, th->ref[0 .. ABBE_THERMAL_MAX_INPUTS - 1],                             \
        th->vmin[0 .. ABBE_THERMAL_MAX_INPUTS - 1], th->vmax[0 .. ABBE_THERMAL_MAX_INPUTS - 1], \
        th->max_step[0 .. ABBE_THERMAL_MAX_INPUTS - 1],                                    \
        th->stuck_s[0 .. ABBE_THERMAL_MAX_INPUTS - 1],                                     \
        th->stuck_res[0 .. ABBE_THERMAL_MAX_INPUTS - 1],                                   \
        th->rise_scale[0 .. ABBE_THERMAL_MAX_INPUTS - 1];                                  \
    loop variant n_in - k;
#define TH_LOOP_TWINS_CHANNELS                                                             \
    loop invariant th_twins_ch: 0 <= c <= n_ch;                                            \
    loop assigns c, th->limit_f[0 .. ABBE_THERMAL_MAX_CHANNELS - 1],                       \
        th->tau_s[0 .. ABBE_THERMAL_MAX_CHANNELS - 1][0 .. ABBE_THERMAL_MAX_TERMS - 1],    \
        th->gain[0 .. ABBE_THERMAL_MAX_CHANNELS - 1][0 .. ABBE_THERMAL_MAX_TERMS - 1];     \
    loop variant n_ch - c;
#define TH_LOOP_TWINS_TERMS                                                                \
    loop invariant th_twins_terms: 0 <= k <= th->n_terms[c];                               \
    loop assigns k, th->tau_s[c][0 .. ABBE_THERMAL_MAX_TERMS - 1],                         \
        th->gain[c][0 .. ABBE_THERMAL_MAX_TERMS - 1];                                      \
    loop variant th->n_terms[c] - k;
#elif defined(__FRAMAC__)
#define TH_ASSERT_FITS assert \true;
#define TH_ASSERT_TIMES assert \true;
#define TH_ASSERT_COUNTED assert \true;
#define TH_LOOP_IN_FLAGS loop invariant \true;
#define TH_LOOP_CH_FLAGS loop invariant \true;
#define TH_LOOP_SLOTS loop invariant \true;
#define TH_LOOP_CH_COUNT loop invariant \true;
#define TH_LOOP_TERM_INPUT loop invariant \true;
#define TH_LOOP_IN_RANGE loop invariant \true;
#define TH_LOOP_CH_RANGE loop invariant \true;
#define TH_LOOP_TERM_RANGE loop invariant \true;
#define TH_LOOP_BUILD_INPUTS loop invariant \true;
#define TH_LOOP_BUILD_CHANNELS loop invariant \true;
#define TH_LOOP_BUILD_TERMS loop invariant \true;
#define TH_LOOP_TWINS_INPUTS loop invariant \true;
#define TH_LOOP_TWINS_CHANNELS loop invariant \true;
#define TH_LOOP_TWINS_TERMS loop invariant \true;
#endif

#if defined(ABBE_PROOF_WP)
/* ---- the contracts WP proves (only with ABBE_PROOF_WP: scripts/prove.sh's
 * "wp thermal" pass; no compiler, no Eva harness sees them) -------------- */
/* internal.h's loads: a function of their bytes (assumed, above) */
/*@ requires \valid_read(p + (0 .. 1));
    assigns \nothing;
    ensures \result == u16_of_bytes(p[0], p[1]); */
static inline uint16_t abbe_ld_u16(const uint8_t *p);
/*@ requires \valid_read(p + (0 .. 3));
    assigns \nothing;
    ensures \result == u32_of_bytes(p[0], p[1], p[2], p[3]); */
static inline uint32_t abbe_ld_u32(const uint8_t *p);
/*@ requires \valid_read(p + (0 .. 3));
    assigns \nothing;
    ensures \result == i32_of_bytes(p[0], p[1], p[2], p[3]); */
static inline int32_t abbe_ld_i32(const uint8_t *p);

/*@ requires t + 16 + 20 * k <= 0xFFFFFFFF;
    assigns \nothing;
    ensures \result == t + 16 + 20 * k; */
static uint32_t th_input(uint32_t t, unsigned k);
/*@ requires t + 16 + 20 * n_inputs + 56 * c <= 0xFFFFFFFF;
    assigns \nothing;
    ensures \result == t + 16 + 20 * n_inputs + 56 * c; */
static uint32_t th_channel(uint32_t t, unsigned n_inputs, unsigned c);
/*@ requires ch + 8 + 12 * k <= 0xFFFFFFFF;
    assigns \nothing;
    ensures \result == ch + 8 + 12 * k; */
static uint32_t th_term(uint32_t ch, unsigned k);
/*@ requires \valid_read(b + (0 .. total - 1));
    assigns \nothing;
    ensures \result == th_u8_l(b, total, at) && \result <= 255; */
static unsigned th_u8(const uint8_t *b, uint32_t total, uint32_t at);
/*@ requires \valid_read(b + (0 .. total - 1));
    assigns \nothing;
    ensures \result == th_u16_l(b, total, at) && \result <= 65535; */
static unsigned th_u16(const uint8_t *b, uint32_t total, uint32_t at);
/*@ requires \valid_read(b + (0 .. total - 1));
    assigns \nothing;
    ensures \result == th_u32_l(b, total, at); */
static uint32_t th_u32(const uint8_t *b, uint32_t total, uint32_t at);
/*@ requires \valid_read(b + (0 .. total - 1));
    assigns \nothing;
    ensures \result == th_i32_l(b, total, at); */
static int32_t th_i32(const uint8_t *b, uint32_t total, uint32_t at);
/*@ requires cap >= 0;
    assigns \nothing;
    ensures \result != 0 <==> (v > cap || v < -cap); */
static int th_abs_over(int32_t v, int32_t cap);
/*@ assigns \nothing;
    ensures \result == (v <= cap ? v : cap); */
static unsigned th_cap(unsigned v, unsigned cap);

/*@ requires table: MIN_TOTAL_SIZE <= total && \valid_read(b + (0 .. total - 1));
    assigns \nothing;
    ensures block_ok: \result == ABBE_OK ==> thermal_block_ok(b, total);
 */
static abbe_status_t check_thermal(const uint8_t *b, uint32_t total);

/*@ requires table: MIN_TOTAL_SIZE <= total && \valid_read(b + (0 .. total - 1));
    requires out: \valid(th) && \separated(th, b + (0 .. total - 1));
    requires block: (u32_of_bytes(b[20], b[21], b[22], b[23]) & ABBE_FEATURE_THERMAL_DYN) != 0 ==>
                    thermal_block_ok(b, total);
    assigns *th;
    ensures model_ok: thermal_model_ok(th);
    ensures no_block: (u32_of_bytes(b[20], b[21], b[22], b[23]) & ABBE_FEATURE_THERMAL_DYN) == 0 ==>
                      th->n_inputs == 0 && th->n_channels == 0;
 */
static void build_thermal(abbe_thermal_model_t *th, const uint8_t *b, uint32_t total);
#endif

#endif /* ABBE_THERMAL_ACSL_H */

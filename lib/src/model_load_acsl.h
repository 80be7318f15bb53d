/* abbe: the invariants an accepted table gives the evaluators, as ACSL
 * predicates (comments only: no code). One statement shared by the loader's
 * contracts (model_load_checks.h, model_load_view.h: WP proves them,
 * scripts/prove.sh) and the evaluator proofs' preconditions
 * (tests/proofs/terms_q_contract.h: the fixed-point term kernel's contract,
 * checked by Eva at each call), so the chain "the loader accepts" ->
 * "the evaluator's precondition" is checked by the tools
 * (docs/proofs.md, "WP: loader contracts"). Not installed. */
#ifndef ABBE_MODEL_LOAD_ACSL_H
#define ABBE_MODEL_LOAD_ACSL_H

#include "internal.h"

/* an axis record's counts as check_counts accepts them (byte offsets of
 * model_load_layout.h: 9 the trend degree, 10 and 11 the harmonics of the
 * two Fourier blocks, 60 the reversal rows). Not the term mask's bits 6 and
 * 7, which check_counts refuses too: no evaluator reads them (popcount6 and
 * build_axis' columns read bits 0..5), and Z3 did not prove the bit test's
 * consequence (docs/proofs.md, "WP: loader contracts") */
/*@ predicate record_counts_ok(uint8_t *rec) =
        (rec[9] <= ABBE_MAX_DEGREE || rec[9] == ABBE_NO_TREND) &&
        rec[10] <= ABBE_MAX_HARMONICS && rec[11] <= ABBE_MAX_HARMONICS &&
        rec[60] <= ABBE_MAX_REVERSAL_ROWS;
 */
/* the three axis records of table b (after its 64-byte header)
 * (spelt out, not quantified: the provers then need no instantiation) */
/*@ predicate table_counts_ok(uint8_t *b) =
        record_counts_ok(b + 64) && record_counts_ok(b + 128) && record_counts_ok(b + 192);
 */
/* bit t of a term mask */
/*@ logic integer mask_bit(integer mask, integer t) = (mask >> t) & 1;
 */
/* the number of bits 0 .. n-1 set in mask */
/*@ logic integer popcount_below(integer mask, integer n) =
        n <= 0 ? 0 : popcount_below(mask, n - 1) + mask_bit(mask, n - 1);
 */
/* trend rows of a trend degree (model_load_layout.h, trend_rows_of) */
/*@ logic integer trend_rows_l(integer degree) = degree == ABBE_NO_TREND ? 0 : degree + 1;
 */
/* basis rows of an axis record (n_basis_of) */
/*@ logic integer n_basis_l(uint8_t *rec) = trend_rows_l(rec[9]) + 2 * rec[10] + 2 * rec[11];
 */
/* term t's column: its rank among the present terms, or 0xFF if absent */
/*@ predicate column_ok(abbe_axis_model_t *ax, integer t) =
        mask_bit(ax->term_mask, t) == 1 ? ax->column[t] == popcount_below(ax->term_mask, t)
                                        : ax->column[t] == 0xFF;
 */
/* columns 0 .. n-1 (the loop of build_axis) */
/*@ predicate columns_below(abbe_axis_model_t *ax, integer n) =
        (n > 0 ==> column_ok(ax, 0)) && (n > 1 ==> column_ok(ax, 1)) && (n > 2 ==> column_ok(ax, 2)) &&
        (n > 3 ==> column_ok(ax, 3)) && (n > 4 ==> column_ok(ax, 4)) && (n > 5 ==> column_ok(ax, 5));
 */
/* the ranges of an axis model's counts, what the term kernels index by:
 * the precondition 'layout' of the kernel's contract
 * (tests/proofs/terms_q_contract.h; Eva checks it at each call) */
/*@ predicate axis_ranges_ok(abbe_axis_model_t *ax) =
        ax->n_terms <= ABBE_TERMS &&
        ax->trend_rows <= ABBE_MAX_DEGREE + 1 &&
        ax->harmonics[0] <= ABBE_MAX_HARMONICS && ax->harmonics[1] <= ABBE_MAX_HARMONICS &&
        ax->n_basis <= ABBE_MAX_BASIS &&
        ax->reversal_rows <= ABBE_MAX_REVERSAL_ROWS &&
        ax->cheb_shift <= 31;
 */
/* the whole layout build_axis makes of an accepted record: the ranges, and
 * the relations tests/proofs/any_layout.h builds its models with (n_terms
 * the mask's popcount, n_basis the rows' sum, column[t] the rank of term t
 * among the present ones or 0xFF) */
/*@ predicate axis_layout_ok(abbe_axis_model_t *ax) =
        axis_ranges_ok(ax) &&
        ax->n_terms == popcount_below(ax->term_mask, ABBE_TERMS) &&
        ax->n_basis == ax->trend_rows + 2 * ax->harmonics[0] + 2 * ax->harmonics[1] &&
        column_ok(ax, 0) && column_ok(ax, 1) && column_ok(ax, 2) &&
        column_ok(ax, 3) && column_ok(ax, 4) && column_ok(ax, 5);
 */

/* The loops' annotations of those contracts (WP_LOOP_*, in the loops of
 * model_load_layout.h, model_load_checks.h, model_load_view.h): the
 * invariants under ABBE_PROOF_WP, a trivial one in the other Frama-C runs
 * (an annotation cannot be empty), so the Eva harnesses see the loops as
 * before; nothing at all for a compiler or cppcheck. */
#if defined(ABBE_PROOF_WP)
#define WP_LOOP_POPCOUNT                                                                   \
    loop invariant wp_popcount: 0 <= t <= ABBE_TERMS && n == popcount_below(mask, t) && n <= t;        \
    loop assigns t, n;                                                                     \
    loop variant ABBE_TERMS - t;
#define WP_LOOP_COUNTS                                                                     \
    loop invariant wp_axes: 0 <= j <= ABBE_AXES;                                                   \
    loop invariant wp_records: (j > 0 ==> record_counts_ok(b + 64)) && (j > 1 ==> record_counts_ok(b + 128)) && \
        (j > 2 ==> record_counts_ok(b + 192));                                             \
    loop assigns j;                                                                        \
    loop variant ABBE_AXES - j;
#define WP_LOOP_COLUMNS                                                                    \
    loop invariant wp_rank: 0 <= t <= ABBE_TERMS && column == popcount_below(ax->term_mask, t);    \
    loop invariant wp_columns: columns_below(ax, t);                                                 \
    loop assigns t, column, ax->column[0 .. ABBE_TERMS - 1];                               \
    loop variant ABBE_TERMS - t;
#define WP_LOOP_BLOCKS                                                                     \
    loop invariant wp_blocks: 0 <= k <= ABBE_BLOCKS;                                                 \
    loop assigns k, ax->freq[0 .. ABBE_BLOCKS - 1], ax->phase_min[0 .. ABBE_BLOCKS - 1];   \
    loop variant ABBE_BLOCKS - k;
#elif defined(__FRAMAC__)
#define WP_LOOP_BLOCKS loop invariant \true;
#define WP_LOOP_POPCOUNT loop invariant \true;
#define WP_LOOP_COUNTS loop invariant \true;
#define WP_LOOP_COLUMNS loop invariant \true;
#endif

#if defined(ABBE_PROOF_WP)
/* The loader's contracts WP proves (scripts/prove.sh, prove_wp: only there is
 * ABBE_PROOF_WP defined; no compiler and no Eva harness sees them). The
 * functions are model_load_layout.h's, model_load_checks.h's and
 * model_load_view.h's; the helpers of internal.h they call are given what
 * WP needs of them (they read, and write nothing). */
/*@ requires \valid_read(p + (0 .. 3));
    assigns \nothing; */
static inline uint32_t abbe_ld_u32(const uint8_t *p);
/*@ requires \valid_read(p + (0 .. 3));
    assigns \nothing; */
static inline int32_t abbe_ld_i32(const uint8_t *p);

/*@ assigns \nothing;
    ensures popcount: \result == popcount_below(mask, ABBE_TERMS) && \result <= ABBE_TERMS; */
static unsigned popcount6(unsigned mask);
/*@ assigns \nothing;
    ensures trend_rows: \result == trend_rows_l(degree); */
static unsigned trend_rows_of(uint8_t degree);
/*@ requires \valid_read(rec + (0 .. 63));
    assigns \nothing;
    ensures n_basis: \result == n_basis_l(rec); */
static uint32_t n_basis_of(const uint8_t *rec);
/*@ requires \valid_read(rec + (0 .. 63));
    assigns \nothing; */
static uint32_t n_matrix_of(const uint8_t *rec);
/*@ requires v != 0;
    assigns \nothing;
    ensures bits: 1 <= \result <= 32; */
static unsigned bit_length(uint32_t v);
/*@ assigns \nothing; */
static uint64_t recip64(uint32_t d);

/*@ requires records: \valid_read(b + (0 .. 64 + 64 * ABBE_AXES - 1));
    assigns \nothing;
    ensures counts_ok: \result == ABBE_OK ==> table_counts_ok(b);
 */
static abbe_status_t check_counts(const uint8_t *b);

/* build_axis: proven (scripts/prove.sh, prove_wp's "wp build_axis": every
 * goal, its loop invariants wp_rank, wp_columns, wp_blocks among them). It
 * stores every field of *ax itself, no memset: the memset's
 * char-pointer view of *ax is a cast WP's Typed memory model hides (with it,
 * layout_ok, the assigns and memset's precondition were not proven). */
/*@ requires out: \valid(ax);
    requires record: \valid_read(rec + (0 .. 63)) && \valid_read(b);
    requires apart: \separated(ax, rec + (0 .. 63));
    requires counts: record_counts_ok(rec);
    assigns *ax;
    ensures layout_ok: axis_layout_ok(ax);
 */
static void build_axis(abbe_axis_model_t *ax, const uint8_t *b, const uint8_t *rec);
#endif

#endif /* ABBE_MODEL_LOAD_ACSL_H */

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

/* The L1 caps of check_ranges (model_load_checks.h): the loader's sum of
 * |coefficient| over one term's words, as the code computes it (each read
 * and index as wrapped in uint32), and the cap each accepted term keeps.
 * The same logic function is the precondition of the term kernel model's
 * table form (tests/proofs/terms_q_l1.c, term_lin_q_table / term_ang_q_table),
 * so "check_ranges accepts" -> "the kernel's L1 precondition" is one
 * statement (docs/proofs.md, "The L1 caps"). */
/* the little-endian word at p (abbe_ld_u32) */
/*@ logic integer ld_u32_l{L}(uint8_t *p) = p[0] + 0x100 * p[1] + 0x10000 * p[2] + 0x1000000 * p[3];
 */
/* a uint32's two's complement int32 (abbe_u32_to_i32), and |v| */
/*@ logic integer i32_of_u32_l(integer u) = u < 0x80000000 ? u : u - 0x100000000;
    logic integer abs_l(integer v) = v < 0 ? -v : v;
 */
/* word i of the coefficient array at byte offset off (coef_word) */
/*@ logic integer coef_word_l{L}(uint8_t *b, integer total, integer off, integer i) =
        total >= 8 && (uint32_t)(off + (uint32_t)(4 * i)) <= total - 8 ?
            ld_u32_l(b + (uint32_t)(off + (uint32_t)(4 * i))) : 0;
 */
/* sum |c| over rows 0 .. n-1 of a term's column of the int32 matrix at off
 * (row r's word r * n_terms + column: column_l1_of) */
/*@ logic integer column_l1{L}(uint8_t *b, integer total, integer off, integer n_terms, integer column, integer n) =
        n <= 0 ? 0 :
        column_l1(b, total, off, n_terms, column, n - 1) +
        abs_l(i32_of_u32_l(coef_word_l(b, total, off, (uint32_t)((uint32_t)((n - 1) * n_terms) + column))));
 */
/* term t of an axis record (mask byte 8, the int32 array's offset at byte 48)
 * within its cap if present: sum |c| <= 2^32 (t < 3, linear) or 2^28, the
 * values of LIN_L1_CAP and ANG_L1_CAP (model_load_layout.h, after this file;
 * check_ranges' proof compares them with the code's caps). Macros that
 * expand in the annotations, not ACSL predicates: Why3's Z3 fails ("Unknown
 * error") on every goal with such a predicate over the table, and proves the
 * same goals with the body written out (docs/proofs.md, "The L1 caps"). */
#define TERM_L1_OK(b, total, rec, t)                                                                   \
    (mask_bit((rec)[8], t) == 1 ==>                                                                   \
     column_l1(b, total, ld_u32_l((rec) + 48), popcount_below((rec)[8], ABBE_TERMS),                   \
               popcount_below((rec)[8], t), n_basis_l(rec)) <= ((t) < 3 ? 0x100000000 : 0x10000000))
/* terms 0 .. n-1 of a record, all its terms, the three records */
#define TERMS_L1_BELOW(b, total, rec, n)                                                               \
    (((n) > 0 ==> TERM_L1_OK(b, total, rec, 0)) && ((n) > 1 ==> TERM_L1_OK(b, total, rec, 1)) &&       \
     ((n) > 2 ==> TERM_L1_OK(b, total, rec, 2)) && ((n) > 3 ==> TERM_L1_OK(b, total, rec, 3)) &&       \
     ((n) > 4 ==> TERM_L1_OK(b, total, rec, 4)) && ((n) > 5 ==> TERM_L1_OK(b, total, rec, 5)))
#define RECORD_L1_OK(b, total, rec) TERMS_L1_BELOW(b, total, rec, ABBE_TERMS)
#define TABLE_L1_OK(b, total)                                                                          \
    (RECORD_L1_OK(b, total, (b) + 64) && RECORD_L1_OK(b, total, (b) + 128) && RECORD_L1_OK(b, total, (b) + 192))

/* The other caps of check_ranges, as the evaluators' proofs state them
 * (tests/proofs/eval_q_any_layout.c: the squareness within +/-2^28; the
 * reversal blocks): the header's three squareness words within
 * SQUARENESS_CAP = 2^28, and per axis the backlash B and the reversal rows r_k
 * (the words n_basis x n_terms + k after the matrix, as coef_word reads them)
 * within REVERSAL_L1_CAP: |B| + sum |r_k| <= 2^31 (the values of
 * model_load_layout.h, written as literals as the L1 caps'). Macros, as
 * TERM_L1_OK. */
/* sum |r_k| over rows 0 .. n-1 of the reversal block at word base */
/*@ logic integer reversal_l1{L}(uint8_t *b, integer total, integer off, integer base, integer n) =
        n <= 0 ? 0 :
        reversal_l1(b, total, off, base, n - 1) +
        abs_l(i32_of_u32_l(coef_word_l(b, total, off, (uint32_t)(base + (n - 1)))));
 */
#define SQUARE_OK(b, k) (abs_l(i32_of_u32_l(ld_u32_l((b) + 48 + 4 * (k)))) <= 0x10000000)
#define SQUARES_BELOW(b, n) (((n) > 0 ==> SQUARE_OK(b, 0)) && ((n) > 1 ==> SQUARE_OK(b, 1)) && ((n) > 2 ==> SQUARE_OK(b, 2)))
#define SQUARENESS_OK(b) SQUARES_BELOW(b, 3)
/* the reversal block's first word: n_basis x n_terms (n_matrix_of) */
#define REVERSAL_BASE(rec) ((uint32_t)(n_basis_l(rec) * popcount_below((rec)[8], ABBE_TERMS)))
#define REVERSAL_OK(b, total, rec)                                                                     \
    (abs_l(i32_of_u32_l(ld_u32_l((rec) + 28))) +                                                        \
         reversal_l1(b, total, ld_u32_l((rec) + 48), REVERSAL_BASE(rec), (rec)[60]) <= 0x80000000)
#define TABLE_REVERSAL_OK(b, total)                                                                    \
    (REVERSAL_OK(b, total, (b) + 64) && REVERSAL_OK(b, total, (b) + 128) && REVERSAL_OK(b, total, (b) + 192))

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
/* abbe_ld_u32's value, the little-endian word (stated, by reading: one line
 * of internal.h), for the L1 caps' pass only (ABBE_PROOF_WP_L1): in the
 * count pass the extra fact per read made Z3 need 18 s instead of 2 for
 * wp_records, and fail under load */
#if defined(ABBE_PROOF_WP_L1)
#define WP_LD_U32_VALUE ensures ld_u32: \result == ld_u32_l(p);
#else
#define WP_LD_U32_VALUE
#endif
/* The loader's contracts WP proves (scripts/prove.sh, prove_wp: only there is
 * ABBE_PROOF_WP defined; no compiler and no Eva harness sees them). The
 * functions are model_load_layout.h's, model_load_checks.h's and
 * model_load_view.h's; the helpers of internal.h they call are given what
 * WP needs of them (they read, and write nothing). */
/*@ requires \valid_read(p + (0 .. 3));
    assigns \nothing;
    WP_LD_U32_VALUE */
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

/* check_ranges' loops (the L1 caps' contract below) */
#if defined(ABBE_PROOF_WP)
#define WP_LOOP_SQUARENESS                                                                 \
    loop invariant wp_squareness: 0 <= k <= 3 && SQUARES_BELOW(b, k);                      \
    loop assigns k;                                                                        \
    loop variant 3 - k;
#define WP_LOOP_L1_AXES                                                                    \
    loop invariant wp_l1_axes: 0 <= j <= ABBE_AXES;                                        \
    loop invariant wp_l1_records: (j > 0 ==> RECORD_L1_OK(b, total, b + 64)) &&            \
        (j > 1 ==> RECORD_L1_OK(b, total, b + 128)) && (j > 2 ==> RECORD_L1_OK(b, total, b + 192)); \
    loop assigns j;                                                                        \
    loop variant ABBE_AXES - j;
#define WP_LOOP_L1_TERMS                                                                   \
    loop invariant wp_l1_rank: 0 <= t <= ABBE_TERMS && column == popcount_below(mask, t);  \
    loop invariant wp_l1_terms: TERMS_L1_BELOW(b, total, rec, t);                          \
    loop assigns t, column;                                                                \
    loop variant ABBE_TERMS - t;
#define WP_LOOP_L1_ROWS                                                                    \
    loop invariant wp_l1_rows: 0 <= r <= n_basis;                                          \
    loop invariant wp_l1_sum: l1 == column_l1(b, total, off_q, n_terms, column, r);        \
    loop invariant wp_l1_bound: column_l1(b, total, off_q, n_terms, column, r) <= r * 0x80000000; \
    loop assigns r, l1;                                                                    \
    loop variant n_basis - r;
#define WP_L1_ROW                                                                          \
    assert wp_l1_next: r + 1 <= n_basis && column_l1(b, total, off_q, n_terms, column, r + 1) == \
        column_l1(b, total, off_q, n_terms, column, r) +                                   \
        abs_l(i32_of_u32_l(coef_word_l(b, total, off_q, (uint32_t)((uint32_t)(r * n_terms) + column))));
#define WP_L1_ABSENT assert wp_l1_absent: mask_bit(mask, t) == 0;
#define WP_L1_PRESENT assert wp_l1_present: TERM_L1_OK(b, total, rec, t);
#define WP_L1_AXIS                                                                         \
    assert wp_l1_axis: (j == 0 ==> RECORD_L1_OK(b, total, b + 64)) &&                      \
        (j == 1 ==> RECORD_L1_OK(b, total, b + 128)) && (j == 2 ==> RECORD_L1_OK(b, total, b + 192));
#define WP_LOOP_REVERSAL_LEFT                                                              \
    loop invariant wp_reversal_rows: 0 <= k <= rec[60];                                    \
    loop invariant wp_reversal_left: left + reversal_l1(b, total, off_q, base, k) ==        \
        0x80000000 - abs_l(i32_of_u32_l(ld_u32_l(rec + 28)));                              \
    loop assigns k, left;                                                                  \
    loop variant rec[60] - k;
#define WP_REV_NEXT                                                                        \
    assert wp_rev_next: reversal_l1(b, total, off_q, base, k + 1) ==                       \
        reversal_l1(b, total, off_q, base, k) + abs_l(i32_of_u32_l(coef_word_l(b, total, off_q, (uint32_t)(base + k))));
#define WP_REV_WRAP assert wp_rev_wrap: (uint32_t)(k + 1) == k + 1 && (uint32_t)(left - a) == left - a;
#define WP_REV_RECORD assert wp_rev_record: REVERSAL_OK(b, total, rec);
#define WP_REV_AXIS                                                                        \
    assert wp_rev_axis: (j == 0 ==> REVERSAL_OK(b, total, b + 64)) &&                      \
        (j == 1 ==> REVERSAL_OK(b, total, b + 128)) && (j == 2 ==> REVERSAL_OK(b, total, b + 192));
#define WP_LOOP_REV_AXES                                                                   \
    loop invariant wp_rev_axes: 0 <= j <= ABBE_AXES;                                       \
    loop invariant wp_rev_records: (j > 0 ==> REVERSAL_OK(b, total, b + 64)) &&            \
        (j > 1 ==> REVERSAL_OK(b, total, b + 128)) && (j > 2 ==> REVERSAL_OK(b, total, b + 192)); \
    loop assigns j;                                                                        \
    loop variant ABBE_AXES - j;
#elif defined(__FRAMAC__)
#define WP_LOOP_SQUARENESS loop invariant \true;
#define WP_LOOP_L1_AXES loop invariant \true;
#define WP_LOOP_L1_TERMS loop invariant \true;
#define WP_LOOP_L1_ROWS loop invariant \true;
#define WP_L1_ROW assert \true;
#define WP_L1_ABSENT assert \true;
#define WP_L1_PRESENT assert \true;
#define WP_L1_AXIS assert \true;
#define WP_LOOP_REVERSAL_LEFT loop invariant \true;
#define WP_REV_NEXT assert \true;
#define WP_REV_WRAP assert \true;
#define WP_REV_RECORD assert \true;
#define WP_REV_AXIS assert \true;
#define WP_LOOP_REV_AXES loop invariant \true;
#endif

#if defined(ABBE_PROOF_WP)
/* The L1 caps' contract (scripts/prove.sh, "wp l1 caps"), with the helpers
 * it calls. abbe_u32_to_i32 (internal.h: a memcpy WP does not model) is
 * given its result, two's complement, by reading. */
/*@ assigns \nothing;
    ensures i32: \result == i32_of_u32_l(u); */
static inline int32_t abbe_u32_to_i32(uint32_t u);
/*@ assigns \nothing;
    ensures abs: \result == abs_l(v); */
static uint64_t abs_i32(int32_t v);
/*@ assigns \nothing;
    ensures mag: \result == abs_l(v); */
static uint32_t mag_i32(int32_t v);
/*@ requires table: \valid_read(b + (0 .. total - 1));
    assigns \nothing;
    ensures word: \result == coef_word_l(b, total, off, i); */
static uint32_t coef_word(const uint8_t *b, uint32_t total, uint32_t off, uint32_t i);
/*@ requires table: \valid_read(b + (0 .. total - 1));
    assigns \nothing;
    ensures column_l1: \result == column_l1(b, total, off_q, n_terms, column, n_basis); */
static uint64_t column_l1_of(const uint8_t *b, uint32_t total, uint32_t off_q, uint32_t n_basis, unsigned n_terms,
                             unsigned column);
/* check_ranges' other caps, each its own function (and pass: "wp caps"): the
 * squareness words, and the reversal caps (|B| + sum |r_k| <= 2^31 on each
 * axis) in a library with the reversal blocks */
/*@ requires header: \valid_read(b + (0 .. 63));
    assigns \nothing;
    ensures squareness_caps: \result == ABBE_OK ==> SQUARENESS_OK(b); */
static abbe_status_t check_squareness(const uint8_t *b);
#if defined(ABBE_NO_REVERSAL)
#define WP_REVERSAL_CAPS
#else
#define WP_REVERSAL_CAPS ensures reversal_caps: \result == ABBE_OK ==> TABLE_REVERSAL_OK(b, total);
/*@ requires table: 260 <= total && \valid_read(b + (0 .. total - 1));
    assigns \nothing;
    WP_REVERSAL_CAPS */
static abbe_status_t check_reversal(const uint8_t *b, uint32_t total);
#endif
/* an accepted table keeps every present term's L1 cap on each axis (260:
 * MIN_TOTAL_SIZE, defined after this file; check_header's accepted_total) */
/*@ requires table: 260 <= total && \valid_read(b + (0 .. total - 1));
    assigns \nothing;
    ensures l1_caps: \result == ABBE_OK ==> TABLE_L1_OK(b, total);
    ensures squareness_caps: \result == ABBE_OK ==> SQUARENESS_OK(b);
    WP_REVERSAL_CAPS */
static abbe_status_t check_ranges(const uint8_t *b, uint32_t total);
#endif

#endif /* ABBE_MODEL_LOAD_ACSL_H */

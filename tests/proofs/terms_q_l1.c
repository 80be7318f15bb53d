/* WP proof of the _q term kernels' accumulation for every table the loader
 * accepts (docs/proofs.md, "The L1 caps"): each term of basis_q.h's kernels
 * (terms_q.c terms6_q, terms_sparse_q.c) is the sum, from the rounding
 * constant of its final shift, of coefficient x basis-row products in int64
 * (MAC: acc += (int64_t)c * b, one row after the other in table order), then
 * the high word (linear terms, shift 32) or the sum shifted by 31 (angular).
 * term_q below is that computation for one term, its rows' coefficients c[]
 * and basis values b[] as arrays; WP proves (Why3 + Z3) that, given
 *   - the loader's L1 cap of the term (check_ranges: sum |c| <= 2^32 linear,
 *     2^28 angular), and
 *   - every basis row within +/-(2^30 + 16) (the enumerated hypotheses
 *     cheb_rows and sincos_range of tests/proofs/hypotheses.c: Chebyshev rows
 *     within 2^30 + 3, harmonics within 2^30 + 11),
 * no int64 sum overflows (WP's RTE guards), the accumulator stays within the
 * rounding constant +/- sum |c| (2^30 + 16), and the term value is within
 * +/-(2^30 + 16) (linear) or +/-(2^27 + 2) (angular): the ranges of
 * tests/proofs/terms_q_contract.h. Not compiled into the library: the model
 * of the kernels' per-term loop, whose shape (start, product, order, shift)
 * is the kernels' (basis_q.h MAC / MAC1, terms_q.c). */
#include <stdint.h>

#include "model_load_layout.h" /* the loader's caps: LIN_L1_CAP, ANG_L1_CAP (check_ranges, check_rotary) */

#define ROW_MAX 1073741840 /* 2^30 + 16 */
#define MAX_ROWS 40

/* l1(c, n): the sum of |c[0]| .. |c[n - 1]|, the loader's L1 (check_ranges) */
/*@ axiomatic L1 {
      logic integer l1{L}(int32_t *c, integer n) reads c[0 .. n - 1];
      axiom l1_empty{L}: \forall int32_t *c; l1(c, 0) == 0;
      axiom l1_next{L}: \forall int32_t *c, integer n; n >= 0 ==>
          l1(c, n + 1) == l1(c, n) + (c[n] < 0 ? -c[n] : c[n]);
    }
 */

/* |c b| <= |c| R when |b| <= R: multiplication by a non-negative factor is
 * monotone (Z3 proves the lemma, the loop uses its instance). */
/* One row's product, |c b| <= |c| R for |b| <= R: a function of its own so
 * that the prover sees a quantifier-free nonlinear goal (Z3's nlsat). */
/*@ requires -ROW_MAX <= bk <= ROW_MAX;
    assigns \nothing;
    ensures -((ck < 0 ? -ck : ck) * ROW_MAX) <= \result <= (ck < 0 ? -ck : ck) * ROW_MAX;
    ensures \result == ck * bk;
 */
static int64_t row_product(int32_t ck, int32_t bk)
{
    return (int64_t)ck * bk;
}

/* The final shifts of the kernels (arithmetic: floor division by 2^32 or
 * 2^31, internal.h's documented assumption). WP's model of a signed >> is not
 * one Z3 decides, so these two postconditions are Eva's (main below, every
 * accumulator value in the range: an interval analysis computes a shift's
 * range exactly); WP uses them at the calls. */
/*@ requires -(0x100000000 * ROW_MAX) + 0x80000000 <= acc <= 0x100000000 * ROW_MAX + 0x80000000;
    assigns \nothing;
    ensures lin_shift: -ROW_MAX <= \result <= ROW_MAX;
 */
static int32_t lin_high_word(int64_t acc)
{
    return (int32_t)(acc >> 32); /* LIN_SHIFT */
}

/*@ requires -(0x10000000 * ROW_MAX) + 0x40000000 <= acc <= 0x10000000 * ROW_MAX + 0x40000000;
    assigns \nothing;
    ensures ang_shift: -0x8000002 <= \result <= 0x8000002;
 */
static int32_t ang_shifted(int64_t acc)
{
    return (int32_t)(acc >> 31); /* ANG_SHIFT */
}

/* One term's accumulation as the kernels do it: from the rounding constant
 * bias, one int64 multiply-add a row in table order. Proven: no overflow, and
 * the sum within bias +/- cap (2^30 + 16). */
/*@ requires rows: 0 <= n <= MAX_ROWS;
    requires \valid_read(c + (0 .. n - 1)) && \valid_read(b + (0 .. n - 1));
    requires basis: \forall integer k; 0 <= k < n ==> -ROW_MAX <= b[k] <= ROW_MAX;
    requires caps: (cap == 0x100000000 && (bias == 0x80000000 || bias == 0x200000000)) ||
                   (cap == 0x10000000 && (bias == 0x40000000 || bias == 0x20000000));
    requires cap: l1(c, n) <= cap;
    assigns \nothing;
    ensures sum: -(cap * ROW_MAX) <= \result - bias <= cap * ROW_MAX;
 */
static int64_t term_acc(const int32_t *c, const int32_t *b, unsigned n, int64_t cap, int64_t bias)
{
    /* the cap holds for every prefix of the rows (|c| >= 0), by a ghost loop
     * from the last row down, one unfolding of l1 a step */
    /*@ ghost
        unsigned i = n;
        /@ loop invariant i <= n;
           loop invariant \forall integer j; i <= j <= n ==> l1(c, j) <= l1(c, n);
           loop assigns i;
           loop variant i; @/
        while (i > 0u) {
            i--;
        }
    */
    int64_t acc = bias;
    /*@ loop invariant 0 <= k <= n;
        loop invariant -(l1(c, k) * ROW_MAX) <= acc - bias <= l1(c, k) * ROW_MAX;
        loop assigns k, acc;
        loop variant n - k;
     */
    for (unsigned k = 0; k < n; k++) {
        /*@ assert l1(c, k + 1) == l1(c, k) + (c[k] < 0 ? -c[k] : c[k]) && l1(c, k + 1) <= l1(c, n); */
        acc += row_product(c[k], b[k]); /* MAC: acc += (int64_t)c * b */
    }
    return acc;
}

/* A linear term: L1 cap 2^32 (2^-8 nm coefficients), the high word. */
/*@ requires rows: 0 <= n <= MAX_ROWS;
    requires \valid_read(c + (0 .. n - 1)) && \valid_read(b + (0 .. n - 1));
    requires basis: \forall integer k; 0 <= k < n ==> -ROW_MAX <= b[k] <= ROW_MAX;
    requires cap: l1(c, n) <= LIN_L1_CAP;
    assigns \nothing;
    ensures lin: -ROW_MAX <= \result <= ROW_MAX;
 */
int32_t term_lin_q(const int32_t *c, const int32_t *b, unsigned n)
{
    const int64_t acc = term_acc(c, b, n, (int64_t)LIN_L1_CAP, 0x80000000); /* LIN_BIAS */
    return lin_high_word(acc);
}

/* An angular term: L1 cap 2^28 (2^-36 rad coefficients), shifted by 31. */
/*@ requires rows: 0 <= n <= MAX_ROWS;
    requires \valid_read(c + (0 .. n - 1)) && \valid_read(b + (0 .. n - 1));
    requires basis: \forall integer k; 0 <= k < n ==> -ROW_MAX <= b[k] <= ROW_MAX;
    requires cap: l1(c, n) <= ANG_L1_CAP;
    assigns \nothing;
    ensures ang: -0x8000002 <= \result <= 0x8000002;
 */
int32_t term_ang_q(const int32_t *c, const int32_t *b, unsigned n)
{
    const int64_t acc = term_acc(c, b, n, (int64_t)ANG_L1_CAP, 0x40000000); /* ANG_BIAS */
    return ang_shifted(acc);
}

/* The same two terms with the precondition in the loader's words
 * (lib/src/model_load_acsl.h): the term's coefficients c[] are its column of
 * the table's int32 matrix at byte offset off, row k's word k * n_terms +
 * column as the loader reads it (coef_word_l: the view the loaded model's
 * coefficient pointer gives the kernels, on paper), and the loader's sum
 * column_l1 of that column is within the cap, which check_ranges' WP-proven
 * postcondition l1_caps gives every present term of an accepted table. The
 * ghost loop shows l1(c, n) is that sum, so term_lin_q's / term_ang_q's
 * precondition holds: the chain check_ranges -> kernel is checked by WP. */
/* The ghost loop both table forms below share (their cap and postcondition
 * differ): by induction on the rows, l1(c, i) is the loader's column_l1 of
 * the column at every i, so at i = n the table's cap is the kernel's. A macro
 * (as the loader's WP_LOOP_* annotations, model_load_acsl.h): the loop's
 * goals stay the functions' own, as before (124 in the pass). */
#define COLUMN_IS_L1                                                                                   \
    unsigned i = 0;                                                                                    \
    /@ loop invariant 0 <= i <= n;                                                                     \
       loop invariant l1(c, i) == column_l1(tb, total, off, n_terms, column, i);                      \
       loop assigns i;                                                                                 \
       loop variant n - i; @/                                                                          \
    while (i < n) {                                                                                    \
        /@ assert l1(c, i + 1) == l1(c, i) + (c[i] < 0 ? -c[i] : c[i]); @/                             \
        /@ assert c[i] == i32_of_u32_l(coef_word_l(tb, total, off, (uint32_t)((uint32_t)(i * n_terms) + column))); @/ \
        /@ assert column_l1(tb, total, off, n_terms, column, i + 1) == column_l1(tb, total, off, n_terms, column, i) + \
               abs_l(i32_of_u32_l(coef_word_l(tb, total, off, (uint32_t)((uint32_t)(i * n_terms) + column)))); @/ \
        i++;                                                                                           \
    }

/*@ requires rows: 0 <= n <= MAX_ROWS;
    requires \valid_read(c + (0 .. n - 1)) && \valid_read(b + (0 .. n - 1));
    requires basis: \forall integer k; 0 <= k < n ==> -ROW_MAX <= b[k] <= ROW_MAX;
    requires view: \forall integer k; 0 <= k < n ==>
        c[k] == i32_of_u32_l(coef_word_l(tb, total, off, (uint32_t)((uint32_t)(k * n_terms) + column)));
    requires loader_cap: column_l1(tb, total, off, n_terms, column, n) <= 0x100000000;
    assigns \nothing;
    ensures lin: -ROW_MAX <= \result <= ROW_MAX;
 */
int32_t term_lin_q_table(const int32_t *c, const int32_t *b, unsigned n, const uint8_t *tb, uint32_t total,
                         uint32_t off, uint32_t n_terms, uint32_t column)
{
    /*@ ghost COLUMN_IS_L1 */
    return term_lin_q(c, b, n);
}

/*@ requires rows: 0 <= n <= MAX_ROWS;
    requires \valid_read(c + (0 .. n - 1)) && \valid_read(b + (0 .. n - 1));
    requires basis: \forall integer k; 0 <= k < n ==> -ROW_MAX <= b[k] <= ROW_MAX;
    requires view: \forall integer k; 0 <= k < n ==>
        c[k] == i32_of_u32_l(coef_word_l(tb, total, off, (uint32_t)((uint32_t)(k * n_terms) + column)));
    requires loader_cap: column_l1(tb, total, off, n_terms, column, n) <= 0x10000000;
    assigns \nothing;
    ensures ang: -0x8000002 <= \result <= 0x8000002;
 */
int32_t term_ang_q_table(const int32_t *c, const int32_t *b, unsigned n, const uint8_t *tb, uint32_t total,
                         uint32_t off, uint32_t n_terms, uint32_t column)
{
    /*@ ghost COLUMN_IS_L1 */
    return term_ang_q(c, b, n);
}

/* The five-axis rotary motions (five_eval_q.c motions_q): per component the
 * same accumulation over the record's rows (2 x harmonics <= 16: sin k t, then
 * cos k t, harmonic by harmonic, the table's row order; the fitted axis' GROUP
 * and the sparse loop alike), from the rounding constant of the final shift,
 * under the same L1 caps (model_load_rotary.h: sum |c| <= 2^32 for X, Y, Z in
 * 2^-8 nm, 2^28 for A, B, C in 2^-36 rad); the basis rows are the harmonics
 * 1..8 (hypothesis sincos_range: within 2^30 + 16). The shifts: 34 (2^-38 nm
 * -> 2^-4 nm) and 30 (2^-66 rad -> 2^-36 rad); the motion within
 * +/-(2^28 + 4) either way: motions_q's contract (five_eval_q.c). */
/*@ requires -(0x100000000 * ROW_MAX) + 0x200000000 <= acc <= 0x100000000 * ROW_MAX + 0x200000000;
    assigns \nothing;
    ensures rot_trans_shift: -0x10000004 <= \result <= 0x10000004;
 */
static int32_t rot_trans_shifted(int64_t acc)
{
    return (int32_t)(acc >> 34); /* Q30 + 4 */
}

/*@ requires -(0x10000000 * ROW_MAX) + 0x20000000 <= acc <= 0x10000000 * ROW_MAX + 0x20000000;
    assigns \nothing;
    ensures rot_ang_shift: -0x10000004 <= \result <= 0x10000004;
 */
static int32_t rot_ang_shifted(int64_t acc)
{
    return (int32_t)(acc >> 30); /* Q30 */
}

/* A linear motion (X, Y, Z): L1 cap 2^32, shift 34. */
/*@ requires rows: 0 <= n <= 16;
    requires \valid_read(c + (0 .. n - 1)) && \valid_read(b + (0 .. n - 1));
    requires basis: \forall integer k; 0 <= k < n ==> -ROW_MAX <= b[k] <= ROW_MAX;
    requires cap: l1(c, n) <= LIN_L1_CAP;
    assigns \nothing;
    ensures motion: -0x10000004 <= \result <= 0x10000004;
 */
int32_t rot_trans_q(const int32_t *c, const int32_t *b, unsigned n)
{
    const int64_t acc = term_acc(c, b, n, (int64_t)LIN_L1_CAP, 0x200000000); /* 2^(34 - 1) */
    return rot_trans_shifted(acc);
}

/* An angular motion (A, B, C): L1 cap 2^28, shift 30. */
/*@ requires rows: 0 <= n <= 16;
    requires \valid_read(c + (0 .. n - 1)) && \valid_read(b + (0 .. n - 1));
    requires basis: \forall integer k; 0 <= k < n ==> -ROW_MAX <= b[k] <= ROW_MAX;
    requires cap: l1(c, n) <= ANG_L1_CAP;
    assigns \nothing;
    ensures motion: -0x10000004 <= \result <= 0x10000004;
 */
int32_t rot_ang_q(const int32_t *c, const int32_t *b, unsigned n)
{
    const int64_t acc = term_acc(c, b, n, (int64_t)ANG_L1_CAP, 0x20000000); /* 2^(30 - 1) */
    return rot_ang_shifted(acc);
}

#ifdef PROOF_EVA_SHIFTS
#include "__fc_builtin.h"

/* Eva: the shifts' postconditions for every accumulator in their ranges. */
int main(void)
{
    volatile int32_t sink;
    sink = lin_high_word(Frama_C_long_interval(-(0x100000000L * ROW_MAX) + 0x80000000L,
                                               0x100000000L * ROW_MAX + 0x80000000L));
    sink = ang_shifted(Frama_C_long_interval(-(0x10000000L * ROW_MAX) + 0x40000000L,
                                             0x10000000L * ROW_MAX + 0x40000000L));
    sink = rot_trans_shifted(Frama_C_long_interval(-(0x100000000L * ROW_MAX) + 0x200000000L,
                                                   0x100000000L * ROW_MAX + 0x200000000L));
    sink = rot_ang_shifted(Frama_C_long_interval(-(0x10000000L * ROW_MAX) + 0x20000000L,
                                                 0x10000000L * ROW_MAX + 0x20000000L));
    (void)sink;
    return 0;
}
#endif

/* Any axis layout the loader accepts (PROOF_ANY_LAYOUT: terms_q_any.c,
 * eval_q_any_layout.c): an abbe_axis_model_t built directly, every field
 * unknown within the invariants the loader's checks establish
 * (lib/src/model_load_checks.h, model_load_view.h), stated here as the
 * preconditions of the evaluation:
 *
 *   term_mask in 0..63 (check_counts: bits 6, 7 clear); n_terms its
 *   popcount; column[t] the rank of term t among the present ones, 0xFF for
 *   an absent one (build_axis);
 *   trend_rows in 0..8 (degree <= ABBE_MAX_DEGREE or ABBE_NO_TREND),
 *   harmonics[b] in 0..8 (ABBE_MAX_HARMONICS), n_basis = trend_rows +
 *   2 harmonics[0] + 2 harmonics[1] (so <= ABBE_MAX_BASIS = 40);
 *   reversal_rows in 0..8 (ABBE_MAX_REVERSAL_ROWS);
 *   coef_q: n_basis x n_terms + reversal_rows int32 words, 4-byte aligned,
 *   readable (check_offsets, array_ok's WP contract), NULL when there are none
 *   (build_axis);
 *   cheb_shift in 0..31 (32 - the bit length of a span >= 1); every other
 *   scalar any value of its type (a superset of what the loader derives:
 *   travel, span, Chebyshev multiplier, Fourier frequencies and phases,
 *   take-up and its rate, backlash reversal, thermal fields).
 *
 * Where the array lies: for a term mask (each its own partition, //@ split)
 * the array of the largest layout with that mask (40 rows, 8 reversal rows)
 * ends exactly where the axis' buffer does, so a read past the largest array
 * the loader can accept for the mask is a read past the buffer (an alarm).
 *
 * Coefficients (the box of any_scalars.h for the largest layout, 40 rows):
 * in a linear column any int32 in [-2^31/40, 2^31/40], in an angular one
 * [-2^27/40, 2^27/40]; a reversal row [-2^30/8, 2^30/8]. With
 * PROOF_LAYOUT_COEF_UNION (eval_q_any_layout.c, where the term kernels run as
 * their proven contract and only the reversal rows are read) every word is
 * any value in the union of these boxes, [-2^27, 2^27]. */
#ifndef PROOF_ANY_LAYOUT_H
#define PROOF_ANY_LAYOUT_H

#include "__fc_builtin.h"
#include <string.h>

#include "internal.h"

#ifndef PROOF_MASK_MIN
#define PROOF_MASK_MIN 0u
#define PROOF_MASK_MAX 63u
#endif
#define ANY_ROWS_MAX ((unsigned)ABBE_MAX_BASIS)
#define ANY_REV_MAX ((unsigned)ABBE_MAX_REVERSAL_ROWS)
#define ANY_COEF_WORDS (ANY_ROWS_MAX * ABBE_TERMS + ANY_REV_MAX)
#define ANY_LIN_BOX ((int32_t)(0x80000000u / ANY_ROWS_MAX))
#define ANY_ANG_BOX ((int32_t)(0x8000000u / ANY_ROWS_MAX))
#define ANY_REV_BOX ((int32_t)(0x40000000u / ANY_REV_MAX))

static uint64_t any_u64(void)
{
    return Frama_C_unsigned_long_long_interval(0u, UINT64_MAX);
}

static int32_t any_i32_in(int32_t lo, int32_t hi)
{
    return Frama_C_int_interval(lo, hi);
}

/* *ax: any layout and scalars within the loader's invariants, its
 * coefficients in coef[ANY_COEF_WORDS] (the axis' own buffer) */
static void any_axis(abbe_axis_model_t *ax, int32_t coef[ANY_COEF_WORDS])
{
    memset(ax, 0, sizeof *ax);
    unsigned mask, n_terms = 0, n_lin = 0;
#if defined(PROOF_LAYOUT_COEF_UNION)
    /* the kernels run as their contract: no partitions */
    mask = Frama_C_unsigned_int_interval(0u, 63u);
#else
    mask = Frama_C_unsigned_int_interval(PROOF_MASK_MIN, PROOF_MASK_MAX);
    /*@ split mask; */
#endif
    for (unsigned t = 0; t < ABBE_TERMS; t++) {
        if ((mask >> t) & 1u) {
            ax->column[t] = (uint8_t)n_terms;
            n_terms++;
            n_lin += (unsigned)(t < 3u);
        } else {
            ax->column[t] = 0xFFu;
        }
    }
    ax->term_mask = (uint8_t)mask;
    ax->n_terms = (uint8_t)n_terms;
    /* an axis without coefficients (no rows, no reversal block: the loader
     * leaves coef_q NULL) or one with (any counts, coef_q into the buffer; a
     * count of 0 there too, a superset): each its own partition */
    unsigned empty, rows_max;
#if defined(PROOF_LAYOUT_COEF_UNION)
    /* coef_q always into the buffer: outside the kernels (whose NULL case
     * terms_q_any.c proves) only the reversal block reads it, and only with
     * reversal rows, i.e. with an array the loader placed (not NULL) */
    empty = 0u;
#else
    empty = Frama_C_unsigned_int_interval(0u, 1u);
    /*@ split empty; */
#endif
    rows_max = empty ? 0u : 1u;
    unsigned trend_rows = Frama_C_unsigned_int_interval(0u, rows_max * ((unsigned)ABBE_MAX_DEGREE + 1u));
    unsigned h0 = Frama_C_unsigned_int_interval(0u, rows_max * ABBE_MAX_HARMONICS);
    unsigned h1 = Frama_C_unsigned_int_interval(0u, rows_max * ABBE_MAX_HARMONICS);
    if (empty && n_terms == 0u) { /* no columns: any rows, still no array */
        trend_rows = Frama_C_unsigned_int_interval(0u, (unsigned)ABBE_MAX_DEGREE + 1u);
        h0 = Frama_C_unsigned_int_interval(0u, ABBE_MAX_HARMONICS);
        h1 = Frama_C_unsigned_int_interval(0u, ABBE_MAX_HARMONICS);
    }
    ax->trend_rows = (uint8_t)trend_rows;
    ax->harmonics[0] = (uint8_t)h0;
    ax->harmonics[1] = (uint8_t)h1;
    ax->n_basis = (uint8_t)(trend_rows + 2u * h0 + 2u * h1);
#if !defined(ABBE_NO_REVERSAL)
    ax->reversal_rows = (uint8_t)Frama_C_unsigned_int_interval(0u, rows_max * ANY_REV_MAX);
#endif
#if defined(PROOF_LAYOUT_COEF_UNION)
    const unsigned first = 0u; /* n_terms is not one value here */
#else
    /* the largest array for this mask ends at the buffer's end */
    const unsigned first = ANY_COEF_WORDS - (ANY_ROWS_MAX * n_terms + ANY_REV_MAX);
#endif
#if defined(PROOF_LAYOUT_COEF_UNION)
    for (unsigned i = 0; i < ANY_COEF_WORDS; i++) {
        coef[i] = any_i32_in(-ANY_REV_BOX, ANY_REV_BOX);
    }
#else
    /* column by column, the rows not unrolled: one weak write per column
     * covers its 40 words (every n_terms-th from the column's first), which
     * keeps each word's box apart from the other columns' at little cost;
     * the words before the array stay 0 (static) */
    for (unsigned c = 0; c < n_terms; c++) {
        const int32_t box = c < n_lin ? ANY_LIN_BOX : ANY_ANG_BOX;
        /*@ loop unroll 0; */
        for (unsigned r = 0; r < ANY_ROWS_MAX; r++) {
            coef[first + r * n_terms + c] = any_i32_in(-box, box);
        }
    }
    for (unsigned k = 0; k < ANY_REV_MAX; k++) {
        coef[first + ANY_ROWS_MAX * n_terms + k] = any_i32_in(-ANY_REV_BOX, ANY_REV_BOX);
    }
#endif
    if (!empty) {
        ax->coef_q = (const uint8_t *)&coef[first];
    }
    /* the scalars: any value (cheb_shift: a span's, 0..31) */
    ax->travel_min_nm = any_i32_in(INT32_MIN, INT32_MAX);
    ax->travel_max_nm = any_i32_in(INT32_MIN, INT32_MAX);
    ax->span_nm = Frama_C_unsigned_int_interval(0u, UINT32_MAX);
    ax->cheb_mul = Frama_C_unsigned_int_interval(0u, UINT32_MAX);
    ax->cheb_shift = (uint8_t)Frama_C_unsigned_int_interval(0u, 31u);
    for (unsigned b = 0; b < ABBE_BLOCKS; b++) {
        ax->freq[b] = any_u64();
        ax->phase_min[b] = any_u64();
    }
    ax->takeup_rate_q46 = any_u64();
    ax->backlash_reversal_q8 = any_i32_in(INT32_MIN, INT32_MAX);
    ax->backlash_takeup_nm = any_i32_in(INT32_MIN, INT32_MAX);
    ax->thermal_expansion_q50 = any_i32_in(INT32_MIN, INT32_MAX);
    ax->thermal_offset_q16 = any_i32_in(INT32_MIN, INT32_MAX);
    ax->thermal_tref_mdegc = any_i32_in(INT32_MIN, INT32_MAX);
}

#endif /* PROOF_ANY_LAYOUT_H */

/* The hypotheses of the Eva proofs: ACSL assertions in lib/src that an
 * interval analysis cannot decide (a value followed through its bits), each
 * checked here on every one of its 2^32 inputs by running the library's own
 * code. scripts/prove.sh compiles this and runs each check next to the Eva
 * harnesses; the assertions may stay unknown to Eva only if these pass. The
 * run is sound for the C semantics because the Eva harnesses prove the code
 * involved free of undefined behaviour (harness 'sincos'; the clamp is
 * unsigned arithmetic and memcpy only).
 *   hypotheses sincos_range: abbe_sincos_q30_pair gives |sin|, |cos| <= 2^30
 *       for every phase (internal.h, abbe_q30_of_bits);
 *   hypotheses mm_clamped: abbe_mm_clamp_bits gives a finite float in
 *       [-2147, 2147] for every float, NaN and infinities included
 *       (internal.h, abbe_mm_to_nm_inline), and abbe_mm_to_nm_inline, which
 *       the float evaluations call on each position, reports exactly the NaNs
 *       and infinities (the evaluation refuses them: ABBE_E_INPUT);
 *   hypotheses f32_finite: abbe_f32_nonfinite is false only for a finite
 *       float (thermal_f32.c, the period of abbe_thermal_init_f32).
 *   hypotheses cheb_rows (and sincos_range's second part): every basis row
 *       the _q kernels stream is within +/-(2^30 + 16), the precondition of
 *       the L1 proof tests/proofs/terms_q_l1.c (WP); checked on the int64
 *       value before its conversion to int32 (basis_q.h: the assertions
 *       cheb_rows in cheb_next_q30, sincos_range in dot2_q30), so the
 *       conversion is in range (-warn-signed-downcast, docs/proofs.md).
 *   hypotheses sincos_norm: sin^2 + cos^2 <= 2^60 + 2^33 for every phase, the
 *       precondition of tests/proofs/turn_q.c (WP). The harmonics are also
 *       the five-axis motions' basis (five_eval_q.c motions_q: the same
 *       rotation, abbe_smlal(abbe_smlal(2^29, a, b), c, d) >> 30 being
 *       dot2_q30's value, from abbe_sincos_q30's unpacked pair; its assertion
 *       'sincos_range' on harmonics 1..8, the precondition of rot_trans_q /
 *       rot_ang_q in terms_q_l1.c).
 * Exit 1 naming the first input that breaks one; 2 for a bad argument. */
#include <inttypes.h>
#include <stdio.h>
#include <string.h>

#include "basis_q.h"

/* sincos_range also checks the harmonics 2..9 the kernels rotate from the
 * pair (basis_q.h: dot2_q30 with the fundamental, the code of the kernels)
 * within +/-BASIS_ROW_MAX: the pairs of a batch of phases first, then each
 * rotation over the batch (so the compiler can vectorize it). */
#define BASIS_ROW_MAX (ABBE_Q30_ONE + 16)
#define HARMONICS 9 /* 8 in the 3-axis kernels; five_eval_q.c's motions_q makes the 9th too (unused) */
#define BATCH 4096u

/* sincos_norm: sin^2 + cos^2 of abbe_sincos_q30_pair within 2^60 + 2^33 for
 * every phase (the precondition of tests/proofs/turn_q.c's WP proof: the
 * trunnion table axis' angle sum turned by the tilt, five_eval_q.c's
 * assertion 'turned_w'). Checked in sincos_range's enumeration: the pairs
 * of a batch are made once for both (abbe_sincos_q30_pair is most of the
 * time of either check). */
#define NORM_MAX (((int64_t)1 << 60) + ((int64_t)1 << 33))

static int sincos_checks(int want_range, int want_norm)
{
    static int32_t s1[BATCH], c1[BATCH], ns1[BATCH], s[BATCH], c[BATCH];
    static int64_t n2[BATCH];
    uint32_t phase = 0u;
    int32_t lo = 0, hi = 0, harm_lo = 0, harm_hi = 0;
    int64_t nlo = INT64_MAX, nhi = 0;
    do {
        for (uint32_t i = 0; i < BATCH; i++) {
            const uint64_t pair = abbe_sincos_q30_pair(phase + i);
            s1[i] = abbe_u32_to_i32((uint32_t)pair);
            c1[i] = abbe_u32_to_i32((uint32_t)(pair >> 32));
            n2[i] = (int64_t)s1[i] * s1[i] + (int64_t)c1[i] * c1[i];
        }
        for (uint32_t i = 0; want_norm && i < BATCH; i++) {
            if (n2[i] > NORM_MAX) {
                printf("sincos_norm: phase 0x%08" PRIx32 ": sin^2 + cos^2 = 2^60 + %" PRId64 ", beyond 2^60 + 2^33\n",
                       phase + i, n2[i] - ((int64_t)1 << 60));
                return 1;
            }
            nlo = n2[i] < nlo ? n2[i] : nlo;
            nhi = n2[i] > nhi ? n2[i] : nhi;
        }
        if (!want_range) {
            phase += BATCH;
            continue;
        }
        for (uint32_t i = 0; i < BATCH; i++) {
            if (s1[i] < -ABBE_Q30_ONE || s1[i] > ABBE_Q30_ONE || c1[i] < -ABBE_Q30_ONE || c1[i] > ABBE_Q30_ONE) {
                printf("sincos_range: phase 0x%08" PRIx32 ": sin %" PRId32 ", cos %" PRId32 " beyond +/-2^30\n",
                       phase + i, s1[i], c1[i]);
                return 1;
            }
            lo = s1[i] < lo ? s1[i] : lo;
            lo = c1[i] < lo ? c1[i] : lo;
            hi = s1[i] > hi ? s1[i] : hi;
            hi = c1[i] > hi ? c1[i] : hi;
            ns1[i] = -s1[i];
            s[i] = s1[i];
            c[i] = c1[i];
        }
        for (unsigned n = 2; n <= HARMONICS; n++) {
            int64_t blo = 0, bhi = 0;
            for (uint32_t i = 0; i < BATCH; i++) {
                /* the int64 values before dot2_q30's conversion (its assertion) */
                const int64_t sn = dot2_wide_q30(s[i], c1[i], c[i], s1[i]);
                const int64_t cn = dot2_wide_q30(c[i], c1[i], s[i], ns1[i]);
                blo = sn < blo ? sn : blo;
                blo = cn < blo ? cn : blo;
                bhi = sn > bhi ? sn : bhi;
                bhi = cn > bhi ? cn : bhi;
                s[i] = (int32_t)sn;
                c[i] = (int32_t)cn;
            }
            if (blo < -BASIS_ROW_MAX || bhi > BASIS_ROW_MAX) {
                printf("sincos_range: phases 0x%08" PRIx32 "..: harmonic %u within [%" PRId64 ", %" PRId64
                       "], beyond 2^30 + %d\n", phase, n, blo, bhi, BASIS_ROW_MAX - ABBE_Q30_ONE);
                return 1;
            }
            harm_lo = blo < harm_lo ? (int32_t)blo : harm_lo; /* within +/-BASIS_ROW_MAX here */
            harm_hi = bhi > harm_hi ? (int32_t)bhi : harm_hi;
        }
        phase += BATCH;
    } while (phase != 0u);
    if (want_range) {
        printf("sincos_range: all 2^32 phases, sin and cos in [%" PRId32 ", %" PRId32 "], the harmonics 2..%d in [%" PRId32
               ", %" PRId32 "]\n", lo, hi, HARMONICS, harm_lo, harm_hi);
    }
    if (want_norm) {
        printf("sincos_norm: all 2^32 phases, sin^2 + cos^2 in [2^60 %+" PRId64 ", 2^60 %+" PRId64 "] (bound 2^60 + 2^33)\n",
               nlo - ((int64_t)1 << 60), nhi - ((int64_t)1 << 60));
    }
    return 0;
}


static int mm_clamped(void)
{
    uint32_t bits = 0u;
    uint32_t n_over = 0u;
    do {
        float mm;
        memcpy(&mm, &bits, sizeof mm);
        const uint32_t over = (uint32_t)((bits & 0x7FFFFFFFu) > 0x45063000u);
        const uint32_t cbits = abbe_mm_clamp_bits(bits);
        float c;
        memcpy(&c, &cbits, sizeof c);
        /* finite by its bits (no float compare of a NaN), then the range */
        if (abbe_f32_bits_nonfinite(cbits) || !(c >= -2147.0f && c <= 2147.0f) ) {
            printf("mm_clamped: input bits 0x%08" PRIx32 ": clamped to bits 0x%08" PRIx32 "\n", bits, cbits);
            return 1;
        }
        /* and the evaluation's refusal test: nonzero exactly for NaN and Inf */
        int32_t nm;
        uint32_t flags = 0u;
        const uint32_t refused = abbe_mm_to_nm_inline(mm, &nm, &flags);
        if (refused != (uint32_t)abbe_f32_bits_nonfinite(bits)) {
            printf("mm_clamped: input bits 0x%08" PRIx32 ": abbe_mm_to_nm_inline returns %" PRIu32 "\n", bits, refused);
            return 1;
        }
        n_over += over;
        bits++;
    } while (bits != 0u);
    printf("mm_clamped: all 2^32 floats clamped into [-2147, 2147] (%" PRIu32 " of them beyond)\n", n_over);
    return 0;
}

/* f32_finite: abbe_f32_nonfinite (the library's test of a float on its bits)
 * is false only for a finite float: a float minus itself is 0 exactly when it
 * is finite (NaN - NaN and inf - inf are NaN). */
static int f32_finite(void)
{
    uint32_t bits = 0u;
    do {
        float f;
        memcpy(&f, &bits, sizeof f);
        volatile float g = f; /* the subtraction made at run time, not folded */
        const int finite = (g - g) == 0.0f;
        if (abbe_f32_nonfinite(f) == finite) {
            printf("f32_finite: bits 0x%08" PRIx32 ": abbe_f32_nonfinite %d for a %s float\n", bits,
                   abbe_f32_nonfinite(f), finite ? "finite" : "non-finite");
            return 1;
        }
        bits++;
    } while (bits != 0u);
    printf("f32_finite: abbe_f32_nonfinite is true exactly for the 2^32 floats' NaNs and infinities\n");
    return 0;
}


/* cheb_rows: the Chebyshev rows T_2..T_7 (trend degree <= 7) the kernels
 * compute by their own recurrence (basis_q.h, cheb_next_q30) are within
 * +/-BASIS_ROW_MAX for every argument u in [-2^30, 2^30] (T_0 = 2^30, T_1 = u:
 * abbe_arg_cheb_q30's range for 0 <= d <= span), in batches so the compiler
 * can vectorize the recurrence. With sincos_range's harmonics this bounds
 * every basis row of the _q kernels: the precondition of the accumulation's WP
 * proof (tests/proofs/terms_q_l1.c). */
#define CHEB_ROWS 8

static int cheb_rows(void)
{
    static int32_t u[BATCH], t_prev[BATCH], t[BATCH];
    int32_t lo = 0, hi = 0;
    for (int64_t first = -ABBE_Q30_ONE; first <= ABBE_Q30_ONE; first += BATCH) {
        const uint32_t count = first + BATCH - 1 <= ABBE_Q30_ONE ? BATCH : (uint32_t)(ABBE_Q30_ONE - first + 1);
        for (uint32_t i = 0; i < count; i++) {
            u[i] = (int32_t)(first + i);
            t_prev[i] = ABBE_Q30_ONE;
            t[i] = u[i];
        }
        for (unsigned k = 2; k < CHEB_ROWS; k++) {
            int64_t blo = 0, bhi = 0;
            for (uint32_t i = 0; i < count; i++) {
                /* the int64 value before cheb_next_q30's conversion (its assertion) */
                const int64_t t_next = cheb_next_wide_q30(u[i], t[i], t_prev[i]);
                t_prev[i] = t[i];
                t[i] = (int32_t)t_next;
                blo = t_next < blo ? t_next : blo;
                bhi = t_next > bhi ? t_next : bhi;
            }
            if (blo < -BASIS_ROW_MAX || bhi > BASIS_ROW_MAX) {
                printf("cheb_rows: u from %" PRId64 ": T_%u within [%" PRId64 ", %" PRId64 "], beyond 2^30 + %d\n",
                       first, k, blo, bhi, BASIS_ROW_MAX - ABBE_Q30_ONE);
                return 1;
            }
            lo = blo < lo ? (int32_t)blo : lo; /* within +/-BASIS_ROW_MAX here */
            hi = bhi > hi ? (int32_t)bhi : hi;
        }
    }
    printf("cheb_rows: all 2^31 + 1 arguments u, T_2..T_%d in [%" PRId32 ", %" PRId32 "] (bound 2^30 + %d)\n",
           CHEB_ROWS - 1, lo, hi, BASIS_ROW_MAX - ABBE_Q30_ONE);
    return 0;
}

/* hypotheses NAME...: each named check, the first that fails ends the run
 * (exit 1); sincos_range and sincos_norm named together share one enumeration */
int main(int argc, char **argv)
{
    int want_range = 0, want_norm = 0, others = 0;
    for (int a = 1; a < argc; a++) {
        if (strcmp(argv[a], "sincos_range") == 0) {
            want_range = 1;
        } else if (strcmp(argv[a], "sincos_norm") == 0) {
            want_norm = 1;
        } else if (strcmp(argv[a], "mm_clamped") == 0 || strcmp(argv[a], "f32_finite") == 0 ||
                   strcmp(argv[a], "cheb_rows") == 0) {
            others = 1;
        } else {
            argc = 0; /* a bad name: the usage */
            break;
        }
    }
    if (argc < 2) {
        fprintf(stderr, "usage: %s NAME... (sincos_range sincos_norm mm_clamped f32_finite cheb_rows)\n", argv[0]);
        return 2;
    }
    if ((want_range || want_norm) && sincos_checks(want_range, want_norm) != 0) {
        return 1;
    }
    for (int a = 1; others && a < argc; a++) {
        if ((strcmp(argv[a], "mm_clamped") == 0 && mm_clamped() != 0) ||
            (strcmp(argv[a], "f32_finite") == 0 && f32_finite() != 0) ||
            (strcmp(argv[a], "cheb_rows") == 0 && cheb_rows() != 0)) {
            return 1;
        }
    }
    return 0;
}

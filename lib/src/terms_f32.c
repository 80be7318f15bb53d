/* abbe: fitted term values of one axis, single precision.
 *
 * The argument reduction is integer (internal.h: one offset d per axis, from
 * which the Chebyshev argument and the Fourier phases follow); the basis and
 * the dot products are float. The basis is streamed: each Chebyshev row (by
 * recurrence) or harmonic (by rotating the block's one sin/cos) is produced
 * and at once multiplied into the term accumulators, so no basis array
 * exists. The float32 coefficients are the int32 coefficients converted (same
 * units: 2^-8 nm, 2^-36 rad), and the values stay in those units: the caller
 * scales each once, folded into the lever arms of Eq. 3.
 */
#include "sincos_f32.h"

/* The basis rows of one axis, in table order, each handed to ROW(b) as it is
 * produced: T_0 = 1 (FIRST_ROW()), T_1 = u, T_k by recurrence; then per
 * Fourier block sin/cos of harmonic 1 (one polynomial evaluation) and the
 * higher harmonics by rotating with the fundamental. A macro so that each
 * kernel below gets it inlined around its own accumulators. */
#define ABBE_BASIS_F32(ax, d, FIRST_ROW, ROW)                                              \
    do {                                                                                   \
        const unsigned trend_rows_ = (ax)->trend_rows;                                     \
        if (trend_rows_ > 0u) {                                                            \
            FIRST_ROW();                                                                   \
            if (trend_rows_ > 1u) {                                                        \
                const float u_ = (float)abbe_arg_cheb_q30((ax), (d)) * 9.31322574615478515625e-10f; \
                const float two_u_ = u_ + u_;                                              \
                float t_prev_ = 1.0f, t_ = u_;                                             \
                ROW(t_);                                                                   \
                for (unsigned k_ = 2; k_ < trend_rows_; k_++) {                            \
                    float t_next_ = two_u_ * t_ - t_prev_; /* T_k = 2u T_(k-1) - T_(k-2) */ \
                    t_prev_ = t_;                                                          \
                    t_ = t_next_;                                                          \
                    ROW(t_);                                                               \
                }                                                                          \
            }                                                                              \
        }                                                                                  \
        for (unsigned blk_ = 0; blk_ < ABBE_BLOCKS; blk_++) {                              \
            const unsigned h_ = (ax)->harmonics[blk_];                                     \
            if (h_ == 0u) {                                                                \
                continue;                                                                  \
            }                                                                              \
            float s1_, c1_;                                                                \
            abbe_sincos_f32_inline(abbe_arg_phase_q32((ax), blk_, (d)), &s1_, &c1_);       \
            float s_ = s1_, c_ = c1_;                                                      \
            for (unsigned n_ = 1;; n_++) {                                                 \
                ROW(s_);                                                                   \
                ROW(c_);                                                                   \
                if (n_ == h_) {                                                            \
                    break;                                                                 \
                }                                                                          \
                float sn_ = s_ * c1_ + c_ * s1_; /* next harmonic: rotate */               \
                c_ = c_ * c1_ - s_ * s1_;                                                  \
                s_ = sn_;                                                                  \
            }                                                                              \
        }                                                                                  \
    } while (0)

#define LD(k) abbe_ld_f32_aligned(row + 4u * (k))

/* A fitted axis: six columns, the accumulators in registers. */
static void terms6_f32(const abbe_axis_model_t *ax, uint32_t d, float value[ABBE_TERMS])
{
    const uint8_t *row = ax->coef_f32;
    float a0 = 0.0f, a1 = 0.0f, a2 = 0.0f, a3 = 0.0f, a4 = 0.0f, a5 = 0.0f;
#define FIRST6() \
    do { a0 = LD(0); a1 = LD(1); a2 = LD(2); a3 = LD(3); a4 = LD(4); a5 = LD(5); row += 24; } while (0)
#define ROW6(b)                                                                            \
    do {                                                                                   \
        const float b_ = (b);                                                              \
        a0 += LD(0) * b_; a1 += LD(1) * b_; a2 += LD(2) * b_;                              \
        a3 += LD(3) * b_; a4 += LD(4) * b_; a5 += LD(5) * b_;                              \
        row += 24;                                                                         \
    } while (0)
    ABBE_BASIS_F32(ax, d, FIRST6, ROW6);
#undef FIRST6
#undef ROW6
    value[0] = a0;
    value[1] = a1;
    value[2] = a2;
    value[3] = a3;
    value[4] = a4;
    value[5] = a5;
}

/* A sparse axis: n_terms < 6 packed columns, spread to the terms at the end. */
static void terms_sparse_f32(const abbe_axis_model_t *ax, uint32_t d, float value[ABBE_TERMS])
{
    const uint8_t *row = ax->coef_f32;
    const unsigned n = ax->n_terms;
    float a[ABBE_TERMS] = {0.0f, 0.0f, 0.0f, 0.0f, 0.0f, 0.0f};
#define FIRSTN() \
    do { for (unsigned k = 0; k < n; k++) a[k] = LD(k); row += 4u * n; } while (0)
#define ROWN(b) \
    do { const float b_ = (b); for (unsigned k = 0; k < n; k++) a[k] += LD(k) * b_; row += 4u * n; } while (0)
    if (n != 0u) {
        ABBE_BASIS_F32(ax, d, FIRSTN, ROWN);
    }
#undef FIRSTN
#undef ROWN
    for (unsigned t = 0; t < ABBE_TERMS; t++) {
        uint8_t col = ax->column[t];
        value[t] = col == 0xFFu ? 0.0f : a[col];
    }
}

#undef LD

void abbe_axis_terms_f32(const abbe_axis_model_t *ax, uint32_t d, float value[ABBE_TERMS])
{
    if (ax->n_terms == ABBE_TERMS) {
        terms6_f32(ax, d, value);
    } else {
        terms_sparse_f32(ax, d, value);
    }
}

abbe_status_t abbe_mm_to_nm_f32(float mm, int32_t *nm, uint32_t *flags)
{
    if (abbe_f32_nonfinite(mm)) {
        return ABBE_E_INPUT;
    }
    /* Beyond +/-2147 mm the nm value would not fit int32. */
    if (mm > 2147.0f) {
        mm = 2147.0f;
        *flags |= ABBE_FLAG_OUT_OF_TRAVEL;
    } else if (mm < -2147.0f) {
        mm = -2147.0f;
        *flags |= ABBE_FLAG_OUT_OF_TRAVEL;
    }
    /* Split into whole mm (exact) and a fraction (exact, |f| < 1): the fraction's
     * product with 1e6 rounds by at most 0.06 nm, where mm * 1e6 would lose 64 nm. */
    int32_t whole = (int32_t)mm;
    float frac = mm - (float)whole;
    float sub = frac * 1.0e6f;
    int32_t sub_nm = (int32_t)(sub + (sub >= 0.0f ? 0.5f : -0.5f));
    *nm = whole * 1000000 + sub_nm;
    return ABBE_OK;
}

/* abbe: spatial error, single precision, x86-64 core (included by
 * eval_f32_sse2.c, the baseline every x86-64 runs, and eval_f32_avx2.c, the
 * same code compiled for x86-64-v3: AVX2 and FMA, chosen at load time).
 *
 * The same evaluation as eval_f32.c (and the same guarantees: integer
 * argument reduction, clamping and flags, NaN handling, a run time that
 * depends on the table's shape only), arranged for four-lane vectors and for
 * an ABI in which a call clobbers every vector register: everything is inline
 * in one function. The three axes share one vector for the position
 * conversion, the offsets, the lever arms and the sin/cos of each Fourier
 * block (on x86-64-v3 also for the phases, in 64-bit lanes); each axis' dot products run two rows per step (kernel_f32_sse2.h);
 * Eq. 3 is a vector fold, (dX, dY, dZ) += W_lin * [d_x, d_y, d_z] + W_a *
 * [e_z, e_z, e_y] + W_b * [e_y, e_x, e_x] per axis.
 */
#ifndef ABBE_EVAL_F32_X86_H
#define ABBE_EVAL_F32_X86_H

#include "kernel_f32_sse2.h"

#if defined(ABBE_F32_SSE2)

static ABBE_ALWAYS_INLINE __m128i load4_i32(const int32_t *p)
{
    return abbe_ld4i(p); /* the model keeps these in four lanes */
}

/* Lane j of a phase vector's sin/cos as [s, c, s, c]. */
static ABBE_ALWAYS_INLINE __m128 lane_pair(__m128 sc_lo, __m128 sc_hi, unsigned j)
{
    /* sc_lo = [sX, cX, sY, cY], sc_hi = [sZ, cZ, ..] */
    return j == 0u ? _mm_movelh_ps(sc_lo, sc_lo) : (j == 1u ? _mm_movehl_ps(sc_lo, sc_lo) : _mm_movelh_ps(sc_hi, sc_hi));
}

/* The six values of axis j as lo = [d_x, d_y, d_z, e_x], hi = [e_y, e_z, ..]. */
static ABBE_ALWAYS_INLINE void axis_values(const abbe_x86_consts_t *k, const abbe_axis_model_t *ax, uint32_t d,
                                           __m128 ub, __m128 p0, __m128 p1, __m128 *lo, __m128 *hi)
{
    if (ax->n_terms == ABBE_TERMS) {
        abbe_axis6_sse2(k, ax, ub, p0, p1, lo, hi);
    } else {
        float v[8] = {0.0f, 0.0f, 0.0f, 0.0f, 0.0f, 0.0f, 0.0f, 0.0f};
        abbe_axis_terms_f32(ax, d, v);
        *lo = _mm_loadu_ps(v);
        *hi = _mm_loadu_ps(v + 4);
    }
}

/* out += wl * lo + wa * [e_z, e_z, e_y] + wb * [e_y, e_x, e_x] */
static ABBE_ALWAYS_INLINE __m128 fold(__m128 out, __m128 lo, __m128 hi, __m128 wl, __m128 wa, __m128 wb)
{
    const __m128 va = ABBE_PERMUTE(hi, 0x05);      /* [hi1, hi1, hi0, hi0] */
    const __m128 t = _mm_shuffle_ps(hi, lo, 0xF0); /* [hi0, hi0, lo3, lo3] */
    const __m128 vb = ABBE_PERMUTE(t, 0xA8);       /* [hi0, lo3, lo3, lo3] */
    out = _mm_add_ps(out, _mm_mul_ps(lo, wl));
    out = _mm_add_ps(out, _mm_mul_ps(va, wa));
    return _mm_add_ps(out, _mm_mul_ps(vb, wb));
}

/* The Chebyshev argument of each axis (abbe_arg_cheb_q30) as floats, in lanes. */
static ABBE_ALWAYS_INLINE __m128 cheb_args(const abbe_x86_consts_t *k, const abbe_model_t *m, __m128i d, uint32_t dx,
                                           uint32_t dy, uint32_t dz)
{
#if defined(__AVX2__)
    /* hi32((d << shift) * mul + 2^31) - 2^30, lanes 0, 2 and 1, 3 */
    const __m128i ds = _mm_sllv_epi32(d, load4_i32((const int32_t *)m->lane_cheb_shift));
    const __m128i mul = load4_i32((const int32_t *)m->lane_cheb_mul);
    const __m128i bias = _mm_srli_epi64(ABBE_KI(k, cheb_bias), 32); /* 2^31 in each 64-bit lane */
    const __m128i even = _mm_srli_epi64(_mm_add_epi64(_mm_mul_epu32(ds, mul), bias), 32);
    const __m128i odd = _mm_add_epi64(_mm_mul_epu32(_mm_srli_epi64(ds, 32), _mm_srli_epi64(mul, 32)), bias);
    const __m128i u = _mm_sub_epi32(_mm_blend_epi32(even, odd, 0x0A), ABBE_KI(k, cheb_one_q30));
    (void)dx;
    (void)dy;
    (void)dz;
    return _mm_mul_ps(_mm_cvtepi32_ps(u), ABBE_KV(k, cheb_scale));
#else
    (void)k;
    (void)d;
    return _mm_mul_ps(_mm_cvtepi32_ps(_mm_setr_epi32(abbe_arg_cheb_q30(&m->axis[0], dx), abbe_arg_cheb_q30(&m->axis[1], dy),
                                                     abbe_arg_cheb_q30(&m->axis[2], dz), 0)),
                      _mm_set1_ps(9.31322574615478515625e-10f));
#endif
}

/* Block b's phase of each axis (abbe_arg_phase_q32), in lanes. */
static ABBE_ALWAYS_INLINE __m128i phases(const abbe_x86_consts_t *k, const abbe_model_t *m, unsigned b, __m128i d,
                                         uint32_t dx, uint32_t dy, uint32_t dz)
{
#if defined(__AVX2__) && defined(ABBE_MODEL_X86_64_LANES)
    /* hi32(d * freq + phase_min) mod 2^32 = hi32(d * f_lo + phase_min) + d * f_hi,
     * in 64-bit lanes; then the low word of each */
    const __m256i d64 = _mm256_cvtepu32_epi64(d);
    const __m256i f = abbe_ld8i(m->lane_freq[b]);
    const __m256i low = _mm256_add_epi64(_mm256_mul_epu32(d64, f), abbe_ld8i(m->lane_phase_min[b]));
    const __m256i ph = _mm256_add_epi64(_mm256_srli_epi64(low, 32), _mm256_mul_epu32(d64, _mm256_srli_epi64(f, 32)));
    (void)dx;
    (void)dy;
    (void)dz;
    return _mm256_castsi256_si128(_mm256_permutevar8x32_epi32(ph, abbe_ld8i(k->even_words)));
#else
    (void)k;
    (void)d;
    const abbe_axis_model_t *ax = m->axis;
    return _mm_setr_epi32((int32_t)abbe_arg_phase_q32(&ax[0], b, dx), (int32_t)abbe_arg_phase_q32(&ax[1], b, dy),
                          (int32_t)abbe_arg_phase_q32(&ax[2], b, dz), 0);
#endif
}

static ABBE_ALWAYS_INLINE abbe_status_t eval_f32_x86(const abbe_model_t *m, const abbe_input_f32_t *in,
                                                     abbe_error_f32_t *out)
{
    const float *pos_mm = in->pos_mm, *dir_state = in->dir_state, *temp_c = in->temp_c;
    float *error_um = out->error_um;
    const uint32_t features = m->features;
    if ((features & (ABBE_FEATURE_BACKLASH | ABBE_FEATURE_THERMAL)) &&
        abbe_f32_extras_nonfinite(features, dir_state, temp_c)) {
        abbe_f32_refuse(out);
        return ABBE_E_INPUT;
    }
    const abbe_x86_consts_t *k = abbe_x86_consts();
    /* ---- positions: float mm -> int nm (abbe_mm_to_nm_inline, four lanes) ---- */
#if defined(__AVX2__)
    const __m128 pos = _mm_insert_ps(abbe_ld2(pos_mm), _mm_load_ss(&pos_mm[2]), 0x20); /* [x, y, z, 0] */
#else
    const __m128 pos = _mm_movelh_ps(abbe_ld2(pos_mm), _mm_load_ss(&pos_mm[2]));
#endif
    __m128i bits = _mm_castps_si128(pos);
    const __m128i mag = _mm_and_si128(bits, ABBE_KI(k, abs_mask));
    const __m128i over = _mm_cmpgt_epi32(mag, ABBE_KI(k, mm_limit)); /* |mm| > 2147, NaN, Inf */
    if (_mm_movemask_epi8(_mm_cmpgt_epi32(mag, ABBE_KI(k, finite_max))) != 0) {
        abbe_f32_refuse(out);
        return ABBE_E_INPUT;
    }
    const __m128i limit = _mm_or_si128(_mm_and_si128(bits, ABBE_KI(k, sign)), ABBE_KI(k, mm_limit));
    bits = _mm_or_si128(_mm_and_si128(over, limit), _mm_andnot_si128(over, bits));
    const __m128 mm = _mm_castsi128_ps(bits);
    const __m128i whole = _mm_cvttps_epi32(mm);
    const __m128 frac_nm = _mm_mul_ps(_mm_sub_ps(mm, _mm_cvtepi32_ps(whole)), ABBE_KV(k, nm_per_mm));
    const __m128i sub_nm = _mm_sub_epi32(_mm_castps_si128(_mm_add_ps(frac_nm, ABBE_KV(k, round_magic))),
                                         ABBE_KI(k, round_magic_bits));
#if defined(__AVX2__)
    const __m128i whole_nm = _mm_mullo_epi32(whole, ABBE_KI(k, mega));
#else
    /* whole * 10^6 (mod 2^32, exact: |whole| <= 2147): lanes 0, 2 and 1, 3 */
    const __m128i w02 = _mm_mul_epu32(whole, ABBE_KI(k, mega));
    const __m128i w13 = _mm_mul_epu32(_mm_srli_epi64(whole, 32), ABBE_KI(k, mega));
    const __m128i whole_nm = _mm_unpacklo_epi32(_mm_shuffle_epi32(w02, 0x08), _mm_shuffle_epi32(w13, 0x08));
#endif
    const __m128i p = _mm_add_epi32(whole_nm, sub_nm);

    /* ---- offsets d = clamp(p) - min, flags ---- */
    const __m128i vmin = load4_i32(m->lane_min_nm);
    const __m128i below = _mm_cmpgt_epi32(vmin, p), above = _mm_cmpgt_epi32(p, load4_i32(m->lane_max_nm));
    __m128i d = _mm_andnot_si128(below, _mm_sub_epi32(p, vmin));
    d = _mm_or_si128(_mm_and_si128(above, load4_i32((const int32_t *)m->lane_span_nm)), _mm_andnot_si128(above, d));
    const uint32_t oot = (uint32_t)(_mm_movemask_epi8(_mm_or_si128(_mm_or_si128(below, above), over)) & 0x0FFF);
    const uint32_t flags = oot != 0u ? ABBE_FLAG_OUT_OF_TRAVEL : 0u;
    const uint32_t dx = (uint32_t)_mm_cvtsi128_si32(d);
    const uint32_t dy = (uint32_t)_mm_cvtsi128_si32(_mm_shuffle_epi32(d, 0x55));
    const uint32_t dz = (uint32_t)_mm_cvtsi128_si32(_mm_shuffle_epi32(d, 0xAA));

    /* ---- sin/cos of each block's fundamental and the Chebyshev arguments,
     * the three axes at once ---- */
    const abbe_axis_model_t *ax = m->axis;
    __m128 sc0_lo, sc0_hi, sc1_lo = _mm_setzero_ps(), sc1_hi = _mm_setzero_ps();
    {
        __m128 s, c;
        abbe_sincos4_sse2(k, phases(k, m, 0u, d, dx, dy, dz), &s, &c);
        sc0_lo = _mm_unpacklo_ps(s, c);
        sc0_hi = _mm_unpackhi_ps(s, c);
        if (m->any_block1) {
            const abbe_x86_consts_t *k1 = abbe_x86_consts_again();
            abbe_sincos4_sse2(k1, phases(k1, m, 1u, d, dx, dy, dz), &s, &c);
            sc1_lo = _mm_unpacklo_ps(s, c);
            sc1_hi = _mm_unpackhi_ps(s, c);
        }
    }
    const __m128 u = cheb_args(k, m, d, dx, dy, dz);

    /* ---- lever arms (p >> 1) - (ref >> 1), half nm, scaled: arm x angle LSB = um ---- */
    const __m128 ka = ABBE_KV(k, um_per_lever);
    const __m128 lev = _mm_mul_ps(_mm_cvtepi32_ps(_mm_sub_epi32(_mm_srai_epi32(p, 1), load4_i32(m->ref_half_nm))), ka);
    const __m128 tool = _mm_mul_ps(_mm_loadu_ps(m->tool_half_nm), ka); /* lane 3 of both is 0 */
    /* W_a, W_b of each axis (Eq. 3 with the tool offset; eval_f32.c lists them
     * term by term), from U = [ty - y, x - tx, tx - x], V = [z + tz, z + tz, y - ty],
     * T1 = [ty, tx, tx], T2 = [tz, tz, ty]:
     *   X: wa = U,                 wb = [-V0, V1, V2]
     *   Y: wa = U - [0, x, -x],    wb = as X
     *   Z: wa = [-T1_0, T1_1, -T1_2], wb = [T2_0, -T2_1, T2_2]          */
    const __m128 tl = _mm_unpacklo_ps(tool, lev);                       /* [tx, x, ty, y] */
    const __m128 u_ = _mm_sub_ps(ABBE_PERMUTE(tl, 0x06), ABBE_PERMUTE(tl, 0x53)); /* [ty, x, tx] - [y, tx, x] */
    const __m128 t2 = ABBE_PERMUTE(tool, 0x1A);                         /* [tz, tz, ty, tx] */
    const __m128 v_ = _mm_add_ps(ABBE_PERMUTE(lev, 0x1A), _mm_xor_ps(t2, ABBE_KV(k, sign_lane2)));
    const __m128 wa_x = u_;
    const __m128 wb_xy = _mm_xor_ps(v_, ABBE_KV(k, sign_lane0));
    const __m128 wa_y = _mm_sub_ps(u_, _mm_xor_ps(ABBE_PERMUTE(lev, 0x03), ABBE_KV(k, sign_lane2))); /* [0, x, -x] */
    const __m128 wa_z = _mm_xor_ps(ABBE_PERMUTE(tool, 0x01),
                                   _mm_or_ps(ABBE_KV(k, sign_lane0), ABBE_KV(k, sign_lane2))); /* [-ty, tx, -tx] */
    const __m128 wb_z = _mm_xor_ps(t2, ABBE_KV(k, sign_lane1));         /* [tz, -tz, ty] */
    const __m128 wl_xy = ABBE_KV(k, um_per_lin_neg), wl_z = ABBE_KV(k, um_per_lin);

    /* ---- the axes, each folded into (dX, dY, dZ) as soon as it is known ---- */
    __m128 lo, hi;
    /* squareness: [y, z, 0] [S_xy, -S_yz, 0] + [z, 0, 0] [-S_xz, 0, 0] */
    __m128 acc = _mm_add_ps(_mm_mul_ps(ABBE_PERMUTE(lev, 0xF9), _mm_loadu_ps(m->square_dx_dy)),
                            _mm_mul_ps(ABBE_PERMUTE(lev, 0xFE), _mm_loadu_ps(m->square_dx_f)));
    axis_values(k, &ax[0], dx, ABBE_PERMUTE(u, 0x00), lane_pair(sc0_lo, sc0_hi, 0u), lane_pair(sc1_lo, sc1_hi, 0u),
                &lo, &hi);
    acc = fold(acc, lo, hi, wl_xy, wa_x, wb_xy);
    axis_values(k, &ax[1], dy, ABBE_PERMUTE(u, 0x55), lane_pair(sc0_lo, sc0_hi, 1u), lane_pair(sc1_lo, sc1_hi, 1u),
                &lo, &hi);
    acc = fold(acc, lo, hi, wl_xy, wa_y, wb_xy);
    axis_values(k, &ax[2], dz, ABBE_PERMUTE(u, 0xAA), lane_pair(sc0_lo, sc0_hi, 2u), lane_pair(sc1_lo, sc1_hi, 2u),
                &lo, &hi);
    acc = fold(acc, lo, hi, wl_z, wa_z, wb_z);

    abbe_st2(error_um, acc);
    _mm_store_ss(&error_um[2], _mm_movehl_ps(acc, acc));
    if (features & (ABBE_FEATURE_BACKLASH | ABBE_FEATURE_THERMAL)) {
        float lev_mm[4];
        _mm_storeu_ps(lev_mm, _mm_mul_ps(lev, _mm_set1_ps(2.0e-6f / 2.9103830456733704e-14f)));
#if defined(ABBE_NO_REVERSAL)
        abbe_f32_add_extras(m, lev_mm, dir_state, temp_c, error_um);
#else
        uint32_t offsets[4];
        _mm_storeu_si128((__m128i *)(void *)offsets, d);
        abbe_f32_add_extras(m, lev_mm, offsets, dir_state, temp_c, error_um);
#endif
    }
    out->flags = flags;
    return ABBE_OK;
}

#endif /* ABBE_F32_SSE2 */
#endif /* ABBE_EVAL_F32_X86_H */

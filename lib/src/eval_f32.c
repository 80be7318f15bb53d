/* abbe: spatial error, single precision (Eq. 3 + Abbe terms + extras).
 *
 * Positions are converted to integer nm first (exact to 0.56 nm), so clamping,
 * the Chebyshev argument and the Fourier phases are those of the fixed-point
 * path. Term values come in the coefficients' units (2^-8 nm, 2^-36 rad); the
 * lever arms are scaled once so that lever x angle is in um, and each axis'
 * six values are folded into (dX, dY, dZ) as soon as they are known, each by
 * one multiply-add: no term array, no per-term scaling.
 */
#include "eval_f32_linear.h"
#include "eval_f32_extras.h"

#if !ABBE_WITH_F32
#error "this is the _f32 variant: compile it with ABBE_WITH_F32=1 (or leave it undefined), or leave the file out"
#endif

#define UM_PER_LIN_LSB ABBE_UM_PER_LIN_LSB

#if !defined(ABBE_F32_SSE2) /* x86-64: eval_f32_sse2.c */
abbe_status_t abbe_eval_f32_core(const abbe_model_t *m, const abbe_input_f32_t *in, abbe_error_f32_t *out)
{
    const uint32_t flags = eval_f32_linear(m, in->pos_mm, in->dir_state, in->temp_c, out->error_um, NULL, NULL);
    if (flags == ABBE_FLAG_INPUT_INVALID) { /* never set by the evaluation itself */
        out->flags = 0;
        return ABBE_E_INPUT;
    }
    out->flags = flags;
    return ABBE_OK;
}
#endif /* !ABBE_F32_SSE2 */

void abbe_f32_refuse(abbe_error_f32_t *out)
{
    out->error_um[0] = out->error_um[1] = out->error_um[2] = 0.0f;
    out->flags = 0;
}

abbe_status_t abbe_error_eval_f32(const abbe_model_t *m, const abbe_input_f32_t *in, abbe_error_f32_t *out)
{
    if (m == NULL || in == NULL || out == NULL) {
        return ABBE_E_ARG;
    }
    return abbe_eval_f32_core(m, in, out);
}

abbe_status_t abbe_error_eval_batch_f32(const abbe_model_t *m, size_t n, const abbe_input_f32_t *in,
                                        abbe_error_f32_t *out)
{
    if (m == NULL || (n > 0u && (in == NULL || out == NULL))) {
        return ABBE_E_ARG;
    }
    abbe_status_t result = ABBE_OK;
    for (size_t i = 0; i < n; i++) {
        if (abbe_eval_f32_core(m, &in[i], &out[i]) != ABBE_OK) {
            out[i].flags = ABBE_FLAG_INPUT_INVALID;
            result = ABBE_E_INPUT;
        }
    }
    return result;
}

abbe_status_t abbe_term_eval_f32(const abbe_model_t *m, unsigned axis, unsigned term, float pos_mm,
                                 float *value)
{
    if (m == NULL || value == NULL || axis >= ABBE_AXES || term >= ABBE_TERMS) {
        return ABBE_E_ARG;
    }
    uint32_t flags = 0;
    int32_t pos_nm;
    if (abbe_mm_to_nm_f32(pos_mm, &pos_nm, &flags) != ABBE_OK) {
        return ABBE_E_INPUT;
    }
    const abbe_axis_model_t *ax = &m->axis[axis];
    float v[ABBE_TERMS];
    abbe_axis_terms_f32(ax, abbe_arg_offset(ax, pos_nm, &flags), v);
    *value = v[term] * (term < 3u ? UM_PER_LIN_LSB : 1.4551915228366852e-5f); /* 2^-36 rad in urad */
    return ABBE_OK;
}

abbe_status_t abbe_reversal_eval_f32(const abbe_model_t *m, unsigned axis, float pos_mm, float *value_um)
{
    if (m == NULL || value_um == NULL || axis >= ABBE_AXES) {
        return ABBE_E_ARG;
    }
    uint32_t flags = 0;
    int32_t pos_nm;
    if (abbe_mm_to_nm_f32(pos_mm, &pos_nm, &flags) != ABBE_OK) {
        return ABBE_E_INPUT;
    }
    const abbe_axis_model_t *ax = &m->axis[axis];
    float r = (float)ax->backlash_reversal_q8;
#if !defined(ABBE_NO_REVERSAL)
    if (ax->reversal_rows != 0u) {
        r += reversal_block_f32(ax, abbe_arg_offset(ax, pos_nm, &flags));
    }
#endif
    *value_um = r * BACKLASH_UM_PER_LSB;
    return ABBE_OK;
}

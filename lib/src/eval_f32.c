/* abbe: spatial error, single precision (Eq. 3 + Abbe terms + extras).
 *
 * Positions are converted to integer nm first (exact to 0.56 nm), so clamping,
 * the Chebyshev argument and the Fourier phases are those of the fixed-point
 * path. Linear values are um, angles urad, lever arms mm: mm * urad = nm.
 */
#include "internal.h"

enum { DX = ABBE_TERM_DX, DY = ABBE_TERM_DY, DZ = ABBE_TERM_DZ, EX = ABBE_TERM_EX, EY = ABBE_TERM_EY, EZ = ABBE_TERM_EZ };

#define NM_PER_MM_INV 1.0e-6f
#define UM_PER_NM 1.0e-3f
#define SQUARENESS_URAD_PER_LSB 1.4551915228366852e-5f /* 2^-36 rad in urad */
#define BACKLASH_UM_PER_LSB 3.90625e-6f                 /* 2^-8 nm in um */
#define EXPANSION_PER_K_PER_LSB 8.8817841970012523e-13f /* 2^-50 per mK, per K */
#define OFFSET_UM_PER_K_PER_LSB 1.52587890625e-5f       /* 2^-16 nm per mK = um per K */

/* p - ref in mm. The difference can need 33 bits; halving it keeps the int32 ->
 * float conversion (one instruction on an FPU) and costs 1 nm of a lever arm. */
static float lever_mm(int32_t pos_nm, int32_t ref_nm)
{
    int64_t half = ((int64_t)pos_nm - ref_nm) / 2;
    return (float)(int32_t)half * 2.0e-6f;
}

static float extras_um(const abbe_model_t *m, unsigned j, float lev_mm, float dir_state, float temp_c)
{
    const abbe_axis_model_t *ax = &m->axis[j];
    float um = 0.0f;
    if (m->features & ABBE_FEATURE_BACKLASH) {
        float s = dir_state > 1.0f ? 1.0f : (dir_state < -1.0f ? -1.0f : dir_state);
        um += 0.5f * s * ((float)ax->backlash_reversal_q8 * BACKLASH_UM_PER_LSB);
    }
    if (m->features & ABBE_FEATURE_THERMAL) {
        float dt = temp_c - (float)ax->thermal_tref_mdegc * 1.0e-3f;
        float strain = (float)ax->thermal_expansion_q50 * EXPANSION_PER_K_PER_LSB * dt;
        um += strain * lev_mm * 1000.0f;
        um += (float)ax->thermal_offset_q16 * OFFSET_UM_PER_K_PER_LSB * dt;
    }
    return um;
}

static int inputs_nonfinite(const abbe_model_t *m, const abbe_input_f32_t *in)
{
    for (unsigned j = 0; j < ABBE_AXES; j++) {
        if (((m->features & ABBE_FEATURE_BACKLASH) && abbe_f32_nonfinite(in->dir_state[j])) ||
            ((m->features & ABBE_FEATURE_THERMAL) && abbe_f32_nonfinite(in->temp_c[j]))) {
            return 1;
        }
    }
    return 0;
}

abbe_status_t abbe_error_eval_f32(const abbe_model_t *m, const abbe_input_f32_t *in, abbe_error_f32_t *out)
{
    if (m == NULL || in == NULL || out == NULL) {
        return ABBE_E_ARG;
    }
    out->error_um[0] = out->error_um[1] = out->error_um[2] = 0.0f;
    out->flags = 0;
    uint32_t flags = 0;
    if (inputs_nonfinite(m, in)) {
        return ABBE_E_INPUT;
    }
    /* One axis at a time, so only the term values stay on the stack; a bad
     * position is found before any output is written. */
    float v[ABBE_AXES][ABBE_TERMS]; /* v[j][0..2] um, v[j][3..5] urad */
    float lev[ABBE_AXES];           /* mm from the reference point */
    for (unsigned j = 0; j < ABBE_AXES; j++) {
        int32_t pos_nm;
        if (abbe_mm_to_nm_f32(in->pos_mm[j], &pos_nm, &flags) != ABBE_OK) {
            return ABBE_E_INPUT;
        }
        abbe_axis_terms_f32(&m->axis[j], pos_nm, v[j], &flags);
        lev[j] = lever_mm(pos_nm, m->reference_nm[j]);
        v[j][j] += extras_um(m, j, lev[j], in->dir_state[j], in->temp_c[j]);
    }
    const float x = lev[0], y = lev[1], z = lev[2];
    const float sxy = (float)m->squareness_q36[0] * SQUARENESS_URAD_PER_LSB;
    const float sxz = (float)m->squareness_q36[1] * SQUARENESS_URAD_PER_LSB;
    const float syz = (float)m->squareness_q36[2] * SQUARENESS_URAD_PER_LSB;
    const float *X = v[0], *Y = v[1], *Z = v[2];

    /* Lever products in nm (mm * urad), scaled to um once per component. */
    float lx_nm = y * (sxy - X[EZ] - Y[EZ]) + z * (-sxz - X[EY] - Y[EY]);
    float ly_nm = x * X[EZ] + z * (X[EX] + Y[EX] - syz);
    float lz_nm = -x * X[EY] + y * (X[EX] + Y[EX]);
    if (m->features & ABBE_FEATURE_TOOL_OFFSET) {
        const float tx = (float)m->tool_offset_nm[0] * NM_PER_MM_INV;
        const float ty = (float)m->tool_offset_nm[1] * NM_PER_MM_INV;
        const float tz = (float)m->tool_offset_nm[2] * NM_PER_MM_INV;
        lx_nm += ty * (X[EZ] + Y[EZ] - Z[EZ]) + tz * (Z[EY] - X[EY] - Y[EY]);
        ly_nm += tx * (Z[EZ] - X[EZ] - Y[EZ]) + tz * (X[EX] + Y[EX] - Z[EX]);
        lz_nm += tx * (X[EY] + Y[EY] - Z[EY]) + ty * (Z[EX] - X[EX] - Y[EX]);
    }
    out->error_um[0] = -X[DX] - Y[DX] + Z[DX] + lx_nm * UM_PER_NM;
    out->error_um[1] = -X[DY] - Y[DY] + Z[DY] + ly_nm * UM_PER_NM;
    out->error_um[2] = -X[DZ] - Y[DZ] + Z[DZ] + lz_nm * UM_PER_NM;
    out->flags = flags;
    return ABBE_OK;
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
    float v[ABBE_TERMS];
    abbe_axis_terms_f32(&m->axis[axis], pos_nm, v, &flags);
    *value = v[term];
    return ABBE_OK;
}

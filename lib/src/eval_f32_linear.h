/* abbe: Eq. 3 in single precision, the body shared by the 3-axis evaluation
 * (eval_f32.c: abbe_eval_f32_core) and the five-axis one (five_eval_f32.c),
 * which also needs the linear axes' angles summed (the tool's orientation
 * error) and the positions in nm (the rotary levers). Inlined into each, so
 * the 3-axis core compiles to what it was (bench/results.md, section 11) and
 * the five-axis one evaluates each axis once. Not installed. The extras it
 * calls (abbe_f32_extras_nonfinite, abbe_f32_add_extras: internal.h) are
 * defined in eval_f32_extras.h, which includes nothing of this file's users.
 *
 * Include with ABBE_EVAL_F32_ROT defined for the five-axis variant: its folds
 * are abbe_axis_fold_rot_f32, which add the angles into w. */
#ifndef ABBE_EVAL_F32_LINEAR_H
#define ABBE_EVAL_F32_LINEAR_H

#include "internal.h"

#define ABBE_UM_PER_LIN_LSB 3.90625e-6f                      /* 2^-8 nm in um */
#define ABBE_UM_PER_HALF_NM_X_ANG_LSB 2.9103830456733704e-14f /* 2 nm x 2^-36 rad in um: 2^-35 x 1e-3 */
#define ABBE_URAD_PER_ANG_LSB 1.4551915228366852e-5f          /* 2^-36 rad in urad */

#if defined(ABBE_EVAL_F32_ROT)
/* Z's angles count +, X's and Y's - (the tool on Z, the workpiece on X and Y).
 * The five-axis kernels add into error_um in place (e is stored there first). */
#define ABBE_FOLD_AXIS(j, ex, ey, ez, rx, ry, rz, lin)                                                          \
    abbe_axis_fold_rot_f32(&m->axis[j], d[j], error_um, w,                                                    \
                           (j) == 2u ? ABBE_URAD_PER_ANG_LSB : -ABBE_URAD_PER_ANG_LSB, rx, ry, rz, lin)
#else
#define ABBE_FOLD_AXIS(j, ex, ey, ez, rx, ry, rz, lin) \
    e = abbe_axis_fold_f32(&m->axis[j], d[j], ex, ey, ez, rx, ry, rz, lin)
#endif

/* The spatial error (um) at pos_mm into error_um; returns its flags, or
 * ABBE_FLAG_INPUT_INVALID alone for a NaN/Inf input (then error_um is 0). p_nm (the
 * five-axis variant): the positions in nm. w (the five-axis variant): += the
 * sum of the axes' angles eps_Z - eps_X - eps_Y, urad. */
static ABBE_ALWAYS_INLINE uint32_t eval_f32_linear(const abbe_model_t *m, const float *pos_mm,
                                                   const float *dir_state, const float *temp_c, float *error_um,
                                                   int32_t *p_nm, float *w)
{
    (void)w;
    const uint32_t features = m->features;
    if ((features & (ABBE_FEATURE_BACKLASH | ABBE_FEATURE_THERMAL)) &&
        abbe_f32_extras_nonfinite(features, dir_state, temp_c)) {
        goto refuse;
    }
    /* Per axis, in one loop (one copy of the code, flash): the position in nm,
     * its offset in the travel, and the lever arm p - ref as (p >> 1) - (ref >> 1)
     * half nm (an exact int32 difference, where p - ref can need 33 bits; 1 nm
     * of the arm at most), scaled so that arm x angle LSB is um. */
    const float ka = ABBE_UM_PER_HALF_NM_X_ANG_LSB, kl = ABBE_UM_PER_LIN_LSB;
    uint32_t flags = 0, bad = 0, d[ABBE_AXES];
    float lev[ABBE_AXES];
    for (unsigned j = 0; j < ABBE_AXES; j++) {
        int32_t p;
        bad |= abbe_mm_to_nm_inline(pos_mm[j], &p, &flags);
        d[j] = abbe_arg_offset(&m->axis[j], p, &flags);
        lev[j] = (float)((p >> 1) - m->ref_half_nm[j]) * ka;
        if (p_nm != NULL) {
            p_nm[j] = p;
        }
    }
    if (bad) {
        goto refuse;
    }
    const float x = lev[0], y = lev[1], z = lev[2];
    const float tx = m->tool_half_nm[0] * ka, ty = m->tool_half_nm[1] * ka, tz = m->tool_half_nm[2] * ka;
    /* (dX, dY, dZ) = squareness + sum over the axes of their share (docs/
     * table-format.md, Eq. 3 with the tool offset): -d_j (+d_z for Z) and the
     * axis' angles crossed with its lever arm r_j (abbe_axis_fold_f32):
     *   X: r = (x - tx, y - ty, -(z + tz)),  Y: r = (-tx, y - ty, -(z + tz)),
     *   Z: r = (tx, ty, tz).
     * squareness: + y S_xy - z S_xz in dX, - z S_yz in dY */
    abbe_vec3f_t e;
    e.x = y * m->squareness_f[0];
    e.x -= z * m->squareness_f[1];
    e.y = -z * m->squareness_f[2];
    e.z = 0.0f;
#if defined(ABBE_EVAL_F32_ROT)
    error_um[0] = e.x;
    error_um[1] = e.y;
    error_um[2] = e.z;
#endif
    const abbe_vec3f_t r_x = {x - tx, y - ty, -(z + tz)};
    ABBE_FOLD_AXIS(0u, e.x, e.y, e.z, r_x.x, r_x.y, r_x.z, -kl);
    const abbe_vec3f_t r_y = {-tx, r_x.y, r_x.z};
    ABBE_FOLD_AXIS(1u, e.x, e.y, e.z, r_y.x, r_y.y, r_y.z, -kl);
    const abbe_vec3f_t r_z = {tx, ty, tz};
    ABBE_FOLD_AXIS(2u, e.x, e.y, e.z, r_z.x, r_z.y, r_z.z, kl);
#if !defined(ABBE_EVAL_F32_ROT)
    error_um[0] = e.x;
    error_um[1] = e.y;
    error_um[2] = e.z;
#endif
    if (features & (ABBE_FEATURE_BACKLASH | ABBE_FEATURE_THERMAL)) {
        const float mm_per_scaled = 2.0e-6f / ka; /* scaled arm -> mm */
        const float lev_mm[ABBE_AXES] = {x * mm_per_scaled, y * mm_per_scaled, z * mm_per_scaled};
        abbe_f32_add_extras(m, lev_mm,
#if !defined(ABBE_NO_REVERSAL)
                            d,
#endif
                            dir_state, temp_c, error_um);
    }
    return flags;
refuse:
    error_um[0] = error_um[1] = error_um[2] = 0.0f;
    return ABBE_FLAG_INPUT_INVALID;
}

#undef ABBE_FOLD_AXIS

#endif /* ABBE_EVAL_F32_LINEAR_H */

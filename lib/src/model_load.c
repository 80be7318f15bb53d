/* abbe: the public load entries, abbe_model_load() (docs/table-format.md)
 * and, compiled into five_load.c, abbe_five_model_load(): validation, then
 * the in-place model view.
 *
 * The loader by concern: model_load_layout.h (the fields, caps and counts),
 * model_load_checks.h (the checks in the spec's order, CHECK_TABLE),
 * model_load_view.h (the model built from a validated table),
 * model_load_rotary.h (a five-axis table's rotary section). They are
 * headers of static functions, not translation units of their own: this
 * file is compiled three times (here the 3-axis loader; five_load.c with
 * ABBE_MODEL_LOAD_FIVE, thermal_load.c with ABBE_MODEL_LOAD_THERMAL), each
 * with its own inlined copies of the checks, and the 3-axis loader's flash
 * stays what it was (bench/results.md). Nothing is written to *model until
 * every check has passed.
 */
#include "internal.h"
#include "model_load_checks.h"
#include "model_load_view.h"
#if defined(ABBE_MODEL_LOAD_FIVE) /* five_load.c */
#include "model_load_rotary.h"
#endif

#if defined(ABBE_MODEL_LOAD_THERMAL)
/* thermal_load.c: abbe_thermal_load follows the include */
#elif !defined(ABBE_MODEL_LOAD_FIVE) /* the 3-axis loader's translation unit */
abbe_status_t abbe_model_load(abbe_model_t *model, const void *blob, size_t size)
{
    if (model == NULL || blob == NULL) {
        return ABBE_E_ARG;
    }
    /* Coefficients are read in place with word loads (one vldr per float on a
     * Cortex-M4F), so the table must start on a 4-byte boundary. */
    if (((uintptr_t)blob & 3u) != 0u) {
        return ABBE_E_ALIGN;
    }
    const uint8_t *b = (const uint8_t *)blob;
    uint32_t total = 0;
    abbe_status_t st;
    CHECK_TABLE(st, b, size, total, 0u);
    if (st != ABBE_OK) {
        return st;
    }
    /* Every check above only read the blob: *model is written from here on,
     * after the last possible failure, so a refused table leaves it untouched
     * (and no second abbe_model_t is needed on the stack). */
    build_model(model, b, total);
    return ABBE_OK;
}

uint32_t abbe_model_crc(const abbe_model_t *model)
{
    return model != NULL ? model->crc : 0u;
}

uint32_t abbe_model_features(const abbe_model_t *model)
{
    return model != NULL ? model->features : 0u;
}

size_t abbe_model_sizeof(void)
{
    return sizeof(abbe_model_t);
}

uint32_t abbe_model_size(const abbe_model_t *model)
{
    return model != NULL ? model->size : 0u;
}

abbe_status_t abbe_model_axis_info(const abbe_model_t *model, unsigned axis, abbe_axis_info_t *info)
{
    if (model == NULL || info == NULL || axis >= ABBE_AXES) {
        return ABBE_E_ARG;
    }
    const abbe_axis_model_t *ax = &model->axis[axis];
    info->travel_min_nm = ax->travel_min_nm;
    info->travel_max_nm = ax->travel_max_nm;
    info->backlash_takeup_nm = (model->features & ABBE_FEATURE_BACKLASH) ? ax->backlash_takeup_nm : 0;
    info->thermal_tref_mdegc = (model->features & ABBE_FEATURE_THERMAL) ? ax->thermal_tref_mdegc : 0;
    return ABBE_OK;
}

#else /* five_load.c: the five-axis loader, with its own copies of the checks */

abbe_status_t abbe_five_model_load(abbe_five_model_t *model, const void *blob, size_t size)
{
    if (model == NULL || blob == NULL) {
        return ABBE_E_ARG;
    }
    if (((uintptr_t)blob & 3u) != 0u) {
        return ABBE_E_ALIGN;
    }
    const uint8_t *b = (const uint8_t *)blob;
    uint32_t total = 0;
    abbe_status_t st;
    CHECK_TABLE(st, b, size, total, ABBE_FEATURE_ROTARY);
    /* total >= ABBE_ROTARY_DATA_START + 4 follows from check_header for a
     * ROTARY table; stated here, where the rotary records are read, for the
     * proof (docs/proofs.md) */
    const int rotary = st == ABBE_OK && (abbe_ld_u32(b + H_FEATURES) & ABBE_FEATURE_ROTARY) != 0u &&
                       total >= ABBE_ROTARY_DATA_START + 4u;
    if (rotary) {
        st = check_rotary(b, total);
    }
    if (st != ABBE_OK) {
        return st; /* *model untouched */
    }
    memset(model, 0, sizeof *model);
    build_model(&model->linear, b, total);
    model->linear.five_view = 1u; /* the compensator's five-axis step may read the whole model */
    if (!rotary) {
        return ABBE_OK; /* a 3-axis table: no rotary errors, kind NONE */
    }
    const uint8_t *h = b + ABBE_ROTARY_HEADER_OFFSET;
    const uint32_t kind = h[RH_KIND];
    model->kind = kind;
    for (unsigned k = 0; k < 3u; k++) {
        model->rot_point_nm[k] = geometry_at(h + RH_ROT_POINT + 4u * k);
        model->offset_nm[k] = geometry_at(h + RH_OFFSET + 4u * k);
        /* |.| <= 2^31 - 2 (GEOMETRY_CAP): fits, so the sum mod 2^32 is the sum */
        model->tilt_pivot_nm[k] = abbe_u32_to_i32((uint32_t)model->rot_point_nm[k] + (uint32_t)model->offset_nm[k]);
        model->squareness_q36[k] = angle_at(h + RH_SQUARENESS + 4u * k);
    }
#if !defined(ABBE_NO_FIVE_KINDS)
    /* validated: check_rotary (a library without the trunnion kinds has only kinds 3-5 here) */
    if ((ABBE_FIVE_KIND_MASK & 0x06u) == 0u || (kind >= ABBE_KIN_XYZBC_HH && kind <= ABBE_KIN_XYZAB_TDR)) {
        /* record 0's and record 1's machine axes and angle slots (A, B, C in alphabetical order):
         * 3 C, B; 4 B, C; 5 B, A */
        static const uint8_t dirs[3][2] = {{2u, 1u}, {1u, 2u}, {1u, 0u}};
        const unsigned i = kind - ABBE_KIN_XYZBC_HH;
        for (unsigned r = 0; r < ABBE_ROTARY_AXES; r++) {
            build_rotary(&model->rotary[r], b, rotary_record(b, r), dirs[i][r]);
            model->sign[r] = rotary_record(b, r)[RA_SIGN] != 0u ? (int8_t)-1 : (int8_t)1;
            model->slot[r] = (uint8_t)(i == 1u ? r : 1u - r);
        }
        for (unsigned k = 0; k < 3u; k++) {
            model->square_ref_nm[k] = geometry_at(h + RH_SQUARE_REF + 4u * k);
        }
        return ABBE_OK;
    }
#endif
    build_rotary(&model->rotary[0], b, rotary_record(b, 0), model->kind == ABBE_KIN_XYZAC_TRT ? 0u : 1u);
    build_rotary(&model->rotary[1], b, rotary_record(b, 1), 2u);
    return ABBE_OK;
}

uint32_t abbe_five_model_kind(const abbe_five_model_t *model)
{
    return model != NULL ? model->kind : ABBE_KIN_NONE;
}

size_t abbe_five_model_sizeof(void)
{
    return sizeof(abbe_five_model_t);
}
#endif /* ABBE_MODEL_LOAD_FIVE */

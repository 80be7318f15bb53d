/* abbe grblHAL plugin core, private: what the core's files share
 * (abbe_grblhal_core.c the state machine, abbe_grblhal_core_eval.c the
 * curvature scan and the inverse, abbe_grblhal_core_line.c the line
 * segmentation, abbe_grblhal_core_upload.c the upload and the stored
 * header). The small helpers are static inline, and each
 * file holds the callees of its hot and its load-time paths, so that the
 * split left the per-segment code and the flash as they were
 * (docs/architecture.md). */
#ifndef ABBE_GRBLHAL_CORE_PRIVATE_H
#define ABBE_GRBLHAL_CORE_PRIVATE_H

#include "abbe_grblhal_core.h"

#define NM_PER_MM 1.0e6f
#define MM_PER_NM 1.0e-6f
#define UM_PER_MM 1.0e3f
#define NO_SLOT 0xFFu

/* mm -> nm, rounded, clamped to int32 (the library clamps to the travel anyway). */
static inline int32_t mm_to_nm(float mm)
{
    float nm = mm * NM_PER_MM;
    if (!(nm < 2147483520.0f)) { /* also NaN: the compensator flags it as input */
        return nm > 0.0f ? INT32_MAX : 0;
    }
    if (nm <= -2147483520.0f) {
        return INT32_MIN + 1;
    }
    return (int32_t)(nm >= 0.0f ? nm + 0.5f : nm - 0.5f);
}

static inline float absf(float x)
{
    return x < 0.0f ? -x : x;
}

/* Square root by Newton's method (no libm in the plugin core; only used at
 * table load and parameter changes). x >= 0. */
static inline float sqrt_pos(float x)
{
    if (!(x > 0.0f)) {
        return 0.0f;
    }
    float r = x > 1.0f ? x : 1.0f;
    for (int i = 0; i < 40; i++) {
        float next = 0.5f * (r + x / r);
        if (absf(next - r) <= 1.0e-7f * next) {
            return next;
        }
        r = next;
    }
    return r;
}

/* 1 while a correction is applied (the last segment end's is not zero). */
static inline int any_correction(const abbe_gh_t *gh)
{
    return gh->last_corr_nm[0] != 0 || gh->last_corr_nm[1] != 0 || gh->last_corr_nm[2] != 0;
}

/* Validate the blob loaded into slot s and derive what segmentation needs
 * (curvature, take-ups, reference temperatures, travel box); s->loaded = 1. */
abbe_status_t abbe_gh_slot_prepare(abbe_gh_slot_t *s);

/* Segment length for the current parameters: the shorter of the running and
 * the queued table's while a swap is pending. */
void abbe_gh_update_seg_len(abbe_gh_t *gh);

#endif /* ABBE_GRBLHAL_CORE_PRIVATE_H */

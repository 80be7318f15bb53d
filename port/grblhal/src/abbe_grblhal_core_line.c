/* abbe grblHAL plugin core, the line segmentation: a line split into
 * segments no longer than the segment length in force, and at the backlash
 * take-ups and the travel box's faces (include/abbe_grblhal_core.h, its
 * header comment has the bound). C99, no heap, no I/O. */
#include <string.h>

#include "abbe_grblhal_core_private.h"

/* Insert t into the ascending list ends[0..*n) unless it lies within 1e-6
 * of an entry (the same break); the last place stays for the line's end (at
 * most 3 x 3 breaks come: a take-up end and two faces per axis). */
static void add_break(float ends[ABBE_GH_LINE_PIECES], uint32_t *n, float t)
{
    uint32_t k = 0u;
    while (k < *n && ends[k] < t) {
        k++;
    }
    if ((k < *n && ends[k] - t < 1.0e-6f) || (k > 0u && t - ends[k - 1u] < 1.0e-6f) ||
        *n >= ABBE_GH_LINE_PIECES - 1u) {
        return;
    }
    for (uint32_t m = *n; m > k; m--) {
        ends[m] = ends[m - 1u];
    }
    ends[k] = t;
    (*n)++;
}

uint32_t abbe_gh_line_begin(const abbe_gh_t *gh, abbe_gh_line_t *line, const float start[ABBE_AXES],
                            const float end[ABBE_AXES])
{
    float len2 = 0.0f;
    const abbe_gh_slot_t *s = gh->running != NO_SLOT ? &gh->slot[gh->running] : NULL;
    line->pieces = 0u;
    for (unsigned j = 0; j < ABBE_AXES; j++) {
        line->start[j] = start[j];
        line->end[j] = end[j];
        float d = end[j] - start[j];
        len2 += d * d;
        /* NOLINTNEXTLINE(bugprone-narrowing-conversions): -1, 0 or 1 fit an int8_t */
        int8_t dir = d > 0.0f ? 1 : (d < 0.0f ? -1 : 0);
        if (s == NULL || dir == 0) {
            continue;
        }
        /* A reversal of an axis with a take-up: its direction state ramps
         * linearly over the take-up distance; a segment that ends where the
         * ramp ends keeps the chord on the model. */
        if (dir != gh->last_dir[j] && s->takeup_mm[j] > 0.0f) {
            float t = s->takeup_mm[j] / absf(d);
            if (t < 1.0f) {
                add_break(line->t_end, &line->pieces, t);
            }
        }
        /* The faces of the travel box the line crosses. */
        float faces[2] = {s->travel_lo_mm[j], s->travel_hi_mm[j]};
        for (unsigned f = 0; f < 2u; f++) {
            float t = (faces[f] - start[j]) / d;
            if (t > 1.0e-6f && t < 1.0f - 1.0e-6f) {
                add_break(line->t_end, &line->pieces, t);
            }
        }
    }
    if (line->pieces >= ABBE_GH_LINE_PIECES) { /* cannot happen: at most 3 x 3 breaks */
        line->pieces = ABBE_GH_LINE_PIECES - 1u;
    }
    line->t_end[line->pieces++] = 1.0f;
    float len = sqrt_pos(len2);
    float t0 = 0.0f;
    line->total = 0u;
    for (uint32_t k = 0; k < line->pieces; k++) {
        float rest = len * (line->t_end[k] - t0);
        uint32_t n = 1u;
        if (gh->seg_len_mm > 0.0f && rest > gh->seg_len_mm) {
            float f = rest / gh->seg_len_mm;
            n = (uint32_t)f;
            if ((float)n < f) {
                n++;
            }
        }
        line->n[k] = n;
        line->total += n;
        t0 = line->t_end[k];
    }
    line->piece = 0u;
    line->k = 0u;
    line->i = 0u;
    return line->total;
}

int abbe_gh_line_next(abbe_gh_line_t *line, float out[ABBE_AXES])
{
    if (line->i >= line->total) {
        return 0;
    }
    line->i++;
    if (line->i == line->total) {
        memcpy(out, line->end, sizeof line->end);
        return 1;
    }
    uint32_t p = line->piece;
    float t0 = p > 0u ? line->t_end[p - 1u] : 0.0f;
    line->k++;
    float t = t0 + (line->t_end[p] - t0) * (float)line->k / (float)line->n[p];
    if (line->k >= line->n[p]) { /* the piece's end: exactly the break */
        t = line->t_end[p];
        line->piece++;
        line->k = 0u;
    }
    for (unsigned j = 0; j < ABBE_AXES; j++) {
        out[j] = line->start[j] + t * (line->end[j] - line->start[j]);
    }
    return 1;
}

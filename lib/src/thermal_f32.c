/* abbe: the thermal runtime, single precision (abbe/thermal.h). */
#include "internal.h"
#include "thermal_common.h"

static float th_absf(float v)
{
    return v < 0.0f ? -v : v;
}

abbe_status_t abbe_thermal_init_f32(abbe_thermal_state_t *st, const abbe_thermal_model_t *thermal, float period_s)
{
    if (st == NULL || thermal == NULL || !(period_s > 0.0f) || abbe_f32_nonfinite(period_s)) {
        return ABBE_E_ARG;
    }
    /* finite by its bits (abbe_f32_nonfinite): a fact of IEEE 754 that Eva does not follow
     * through the bits, checked on every float by tests/proofs/hypotheses.c */
    //@ assert f32_finite: \is_finite(period_s);
    th_init_common(st, thermal);
    if (thermal->n_channels != 0u) {
        float fade_s = (float)thermal->fade_ms * 0.001f;
        st->fade_step = period_s < fade_s ? period_s / fade_s : 1.0f;
        float calls = thermal->max_gap_s / period_s;
        st->gap_calls = 0x80000000u; /* a period below max_gap / 2^31 (+inf calls included) */
        if (calls < 2147483648.0f) {
            st->gap_calls = (uint32_t)calls;
        }
    }
    return ABBE_OK;
}

/* out = sum of w x tip by axis; fading = some weight short of its target. */
static void th_mix_f32(abbe_thermal_state_t *st)
{
    const abbe_thermal_model_t *th = st->model;
    float out[3] = {0.0f, 0.0f, 0.0f};
    unsigned fading = 0u;
    for (unsigned c = 0; c < th->n_channels; c++) {
        int up = st->ch_state[c] == TH_CH_RUN && !st->gap;
        fading |= up ? (st->w[c] < 1.0f) : (st->w[c] > 0.0f);
        out[st->tip_axis[c]] += st->w[c] * st->tip[c];
    }
    st->out[0] = out[0];
    st->out[1] = out[1];
    st->out[2] = out[2];
    st->fading = (uint8_t)fading;
}

abbe_status_t abbe_thermal_update_f32(abbe_thermal_state_t *st, const float x[], uint32_t valid_mask, float dt_s)
{
    if (st == NULL || x == NULL || st->model == NULL) {
        return ABBE_E_ARG;
    }
    const abbe_thermal_model_t *th = st->model;
    if (st->seen != 0u && (!(dt_s > 0.0f) || abbe_f32_nonfinite(dt_s))) {
        return ABBE_E_ARG;
    }
    if (st->seen == 0u) {
        dt_s = 0.0f;
    }
    uint32_t flags = 0u, faults = 0u;
    int gap = st->seen != 0u && dt_s > th->max_gap_s;
    if (gap) {
        flags |= ABBE_THERMAL_F_GAP;
    }
    for (unsigned k = 0; k < th->n_inputs; k++) {
        float v = x[k];
        uint32_t bit = 1u << k, fault = 0u;
        if ((valid_mask & bit) == 0u) {
            fault = ABBE_THERMAL_F_OPEN;
        } else if (!(v >= th->vmin[k] && v <= th->vmax[k])) { /* NaN too */
            fault = ABBE_THERMAL_F_RANGE;
        } else {
            if ((st->seen & bit) != 0u && th_absf(v - st->x_prev[k]) > th->max_step[k]) {
                fault = ABBE_THERMAL_F_STEP;
            }
            if (th->stuck_ms[k] != 0u) { /* still near the anchor: the time adds up */
                if ((st->seen & bit) != 0u && th_absf(v - st->x_anchor[k]) <= th->stuck_res[k]) {
                    st->still_s[k] += dt_s;
                } else {
                    st->x_anchor[k] = v;
                    st->still_s[k] = 0.0f;
                }
                if (fault == 0u && st->still_s[k] >= th->stuck_s[k]) {
                    fault = ABBE_THERMAL_F_STUCK;
                }
            }
            st->x_prev[k] = v; /* a credible reading: the next step is measured from it */
            st->seen |= bit;
        }
        if (fault != 0u) {
            faults |= bit;
            flags |= fault;
        }
    }
    for (unsigned c = 0; c < th->n_channels; c++) {
        st->age_s[c] += dt_s;
        unsigned act = th_channel_action(st, c, faults, gap, !(st->w[c] > 0.0f));
        if (act == 0u) {
            continue;
        }
        float dt = st->age_s[c];
        st->age_s[c] = 0.0f;
        float y = 0.0f;
        for (unsigned k = 0; k < th->n_terms[c]; k++) {
            unsigned i = th->term_input[c][k];
            float u = (st->x_prev[i] - th->ref[i]) * th->rise_scale[i];
            float s = st->s[c][k];
            if (act == 1u) {
                s = u;
            } else {
                s += dt / (th->tau_s[c][k] + dt) * (u - s);
            }
            st->s[c][k] = s;
            y += th->gain[c][k] * s;
        }
        if (y > th->limit_f[c]) {
            y = th->limit_f[c];
            flags |= ABBE_THERMAL_F_LIMIT;
        } else if (y < -th->limit_f[c]) {
            y = -th->limit_f[c];
            flags |= ABBE_THERMAL_F_LIMIT;
        }
        st->y[c] = y;
        uint8_t out = th->output[c];
        float lever = th->tool_z_mm * 1e-3f; /* urad x mm = 1e-3 um */
        st->tip[c] = out == ABBE_THERMAL_OUT_A ? -y * lever : (out == ABBE_THERMAL_OUT_B ? y * lever : y);
    }
    st->input_fault = faults;
    st->since_update = 0u;
    st->gap = 0u;
    th_mix_f32(st);
    st->flags = th_state_flags(st, flags);
    st->events |= st->flags;
    return ABBE_OK;
}

/* One fade step of every channel toward its target (1 running, else 0), the
 * mix and the flags in the same pass (HOLD changes only at a sample). */
static inline void th_fade_f32(abbe_thermal_state_t *st, float step)
{
    const abbe_thermal_model_t *th = st->model;
    float out[3] = {0.0f, 0.0f, 0.0f};
    unsigned fading = 0u;
    for (unsigned c = 0; c < th->n_channels; c++) {
        float w = st->w[c];
        if (st->ch_state[c] == TH_CH_RUN && !st->gap) {
            w += step;
            w = w > 1.0f ? 1.0f : w;
            fading |= w < 1.0f;
        } else {
            w -= step;
            w = w < 0.0f ? 0.0f : w;
            fading |= w > 0.0f;
        }
        st->w[c] = w;
        out[st->tip_axis[c]] += w * st->tip[c];
    }
    st->out[0] = out[0];
    st->out[1] = out[1];
    st->out[2] = out[2];
    st->fading = (uint8_t)fading;
    st->flags = (st->flags & ~(ABBE_THERMAL_F_FADING | ABBE_THERMAL_F_GAP)) | (fading ? ABBE_THERMAL_F_FADING : 0u) |
                (st->gap ? ABBE_THERMAL_F_GAP : 0u);
}

void abbe_thermal_apply_f32(abbe_thermal_state_t *st, float err_um[3])
{
    if (st->since_update <= st->gap_calls) {
        st->since_update++; /* saturates at gap_calls + 1 */
    }
    if (st->since_update > st->gap_calls && !st->gap && st->seen != 0u) {
        st->gap = 1u; /* missing samples: fade everything out */
        st->fading = 1u;
        st->events |= ABBE_THERMAL_F_GAP;
    }
    if (st->fading) {
        th_fade_f32(st, st->fade_step);
    }
    err_um[0] += st->out[0];
    err_um[1] += st->out[1];
    err_um[2] += st->out[2];
}

void abbe_thermal_apply_ms_f32(abbe_thermal_state_t *st, float err_um[3], uint32_t elapsed_ms)
{
    const abbe_thermal_model_t *th = st->model;
    /* since_update counts ms here (saturating just past max_gap) */
    uint32_t cap = th->max_gap_ms + 1u;
    st->since_update = elapsed_ms >= cap - st->since_update ? cap : st->since_update + elapsed_ms;
    if (st->since_update > th->max_gap_ms && !st->gap && st->seen != 0u) {
        st->gap = 1u;
        st->fading = 1u;
        st->events |= ABBE_THERMAL_F_GAP;
    }
    if (st->fading) {
        float step = elapsed_ms >= th->fade_ms ? 1.0f : (float)elapsed_ms / (float)th->fade_ms;
        th_fade_f32(st, step);
    }
    err_um[0] += st->out[0];
    err_um[1] += st->out[1];
    err_um[2] += st->out[2];
}

unsigned abbe_thermal_channels_f32(const abbe_thermal_state_t *st, float y[ABBE_THERMAL_MAX_CHANNELS])
{
    if (st == NULL || st->model == NULL || y == NULL) {
        return 0u;
    }
    for (unsigned c = 0; c < st->model->n_channels; c++) {
        y[c] = st->y[c];
    }
    return st->model->n_channels;
}

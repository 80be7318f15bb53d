/* abbe: the thermal runtime, fixed point (abbe/thermal.h).
 *
 * Inputs in milli-units (m degC; rpm, which is milli-krpm), lag states in
 * milli-units x 2^12 (int64: |rise| <= 2^21 by the block's ranges, so
 * |state| <= 2^33 and a step's product with its Q28 weight <= 2^62), weights
 * dt / (tau + dt) in Q28 (cached per channel while dt repeats: the 64-bit
 * division runs only when the sample spacing changes), channel values in nm or
 * nrad (gain 2^-16 um per unit x milli-units = 2^-16 nm). */
#include "internal.h"
#include "thermal_common.h"

#define TH_STATE_BITS 12u
#define TH_W_BITS 28u
#define TH_FADE_ONE ((uint32_t)1 << 24)
#define TH_W_ONE ((uint32_t)1 << TH_W_BITS)
/* |u| = |x - ref| x 2^12 <= 2^21 x 2^12 (the block's value cap 2^20, thermal_load.c) */
#define TH_STATE_MAX ((int64_t)1 << 33)

abbe_status_t abbe_thermal_init_q(abbe_thermal_state_t *st, const abbe_thermal_model_t *thermal, uint32_t period_us)
{
    if (st == NULL || thermal == NULL || period_us == 0u) {
        return ABBE_E_ARG;
    }
    th_init_common(st, thermal);
    if (thermal->n_channels != 0u) {
        uint64_t fade_us = (uint64_t)thermal->fade_ms * 1000u;
        uint64_t step = (((uint64_t)period_us << 24) + fade_us / 2u) / fade_us;
        st->fade_step_q24 = step < 1u ? 1u : (step > TH_FADE_ONE ? TH_FADE_ONE : (uint32_t)step);
        uint64_t calls = (uint64_t)thermal->max_gap_ms * 1000u / period_us;
        st->gap_calls = calls < 0x80000000u ? (uint32_t)calls : 0x80000000u;
    }
    return ABBE_OK;
}

static void th_mix_q(abbe_thermal_state_t *st)
{
    const abbe_thermal_model_t *th = st->model;
    int64_t out[3] = {0, 0, 0};
    unsigned fading = 0u;
    /*@ loop unroll ABBE_THERMAL_MAX_CHANNELS; */
    for (unsigned c = 0; c < th->n_channels; c++) {
        int up = st->ch_state[c] == TH_CH_RUN && !st->gap;
        fading |= up ? (st->wq24[c] < TH_FADE_ONE) : (st->wq24[c] > 0u);
        /* the weight <= 1 (th_fade_q keeps it there), stated for the proof as in th_fade_q */
        out[st->tip_axis[c]] += (int64_t)(st->wq24[c] < TH_FADE_ONE ? st->wq24[c] : TH_FADE_ONE) * st->tipq[c];
    }
    for (unsigned a = 0; a < 3u; a++) { /* two channels per axis at most, each within 2^31: clamp the sum */
        st->outq[a] = (int32_t)abbe_clamp_i64(abbe_shr_round(out[a], 24u), -INT32_MAX, INT32_MAX);
    }
    st->fading = (uint8_t)fading;
}

static int64_t th_div_round(int64_t num, int64_t den)
{
    return num >= 0 ? (num + den / 2) / den : -((-num + den / 2) / den);
}

abbe_status_t abbe_thermal_update_q(abbe_thermal_state_t *st, const int32_t x_milli[], uint32_t valid_mask,
                                    uint32_t dt_ms)
{
    if (st == NULL || x_milli == NULL || st->model == NULL) {
        return ABBE_E_ARG;
    }
    const abbe_thermal_model_t *th = st->model;
    if (st->seen != 0u && dt_ms == 0u) {
        return ABBE_E_ARG;
    }
    if (st->seen == 0u) {
        dt_ms = 0u;
    }
    uint32_t flags = 0u, faults = 0u;
    int gap = st->seen != 0u && dt_ms > th->max_gap_ms;
    if (gap) {
        flags |= ABBE_THERMAL_F_GAP;
    }
    for (unsigned k = 0; k < th->n_inputs; k++) {
        int32_t v = x_milli[k];
        uint32_t bit = 1u << k, fault = 0u;
        if ((valid_mask & bit) == 0u) {
            fault = ABBE_THERMAL_F_OPEN;
        } else if (v < th->vmin_milli[k] || v > th->vmax_milli[k]) {
            fault = ABBE_THERMAL_F_RANGE;
        } else {
            int32_t d = v - st->xq_prev[k]; /* both within +/-2^20 */
            if ((st->seen & bit) != 0u && (d > th->max_step_milli[k] || d < -th->max_step_milli[k])) {
                fault = ABBE_THERMAL_F_STEP;
            }
            if (th->stuck_ms[k] != 0u) { /* still near the anchor: the time adds up (saturating) */
                int32_t da = v - st->xq_anchor[k]; /* both within +/-2^20 */
                if ((st->seen & bit) != 0u && da <= th->stuck_res_milli[k] && da >= -th->stuck_res_milli[k]) {
                    uint32_t still = st->still_ms[k] + dt_ms;
                    st->still_ms[k] = still < st->still_ms[k] ? 0xFFFFFFFFu : still;
                } else {
                    st->xq_anchor[k] = v;
                    st->still_ms[k] = 0u;
                }
                if (fault == 0u && st->still_ms[k] >= th->stuck_ms[k]) {
                    fault = ABBE_THERMAL_F_STUCK;
                }
            }
            st->xq_prev[k] = v;
            st->seen |= bit;
        }
        if (fault != 0u) {
            faults |= bit;
            flags |= fault;
        }
    }
    /*@ loop unroll ABBE_THERMAL_MAX_CHANNELS; */ /* the proof: each channel's sums apart (no widening) */
    for (unsigned c = 0; c < th->n_channels; c++) {
        uint32_t age = st->age_ms[c] + dt_ms;
        st->age_ms[c] = age < st->age_ms[c] || age > 0x80000000u ? 0x80000000u : age; /* saturate at 2^31 ms */
        unsigned act = th_channel_action(st, c, faults, gap, st->wq24[c] == 0u);
        if (act == 0u) {
            continue;
        }
        uint32_t dt = st->age_ms[c];
        st->age_ms[c] = 0u;
        int recompute = act == 2u && dt != st->wq_dt_ms[c];
        st->wq_dt_ms[c] = act == 2u ? dt : st->wq_dt_ms[c];
        int64_t acc = 0;
        /*@ loop unroll ABBE_THERMAL_MAX_TERMS; */
        for (unsigned k = 0; k < th->n_terms[c]; k++) {
            unsigned i = th->term_input[c][k];
            int64_t u = (int64_t)(st->xq_prev[i] - th->ref_milli[i]) * ((int64_t)1 << TH_STATE_BITS);
            /* the lag state and the weight as stored, held to their bounds: |s| <= TH_STATE_MAX
             * (s only moves towards u, |u| <= TH_STATE_MAX), w <= 1 (dt / (tau + dt)); these
             * never bind, they state the bounds for the proof (tests/proofs/thermal_update.c),
             * whose state after any number of samples is not related to the inputs */
            int64_t s = abbe_clamp_i64(st->sq[c][k], -TH_STATE_MAX, TH_STATE_MAX);
            if (act == 1u) {
                s = u;
            } else {
                if (recompute) {
                    /* a term without lag (tau 0) takes the sample whole: dt / (0 + dt) = 1 for every
                     * dt >= 1 (a step's dt is the channel's age, >= 1 ms: dt_ms >= 1 once seen), so
                     * the division is only made where its divisor is evidently > 0 */
                    uint32_t tau = th->tau_ms[c][k];
                    st->wq28[c][k] = tau == 0u ? TH_W_ONE
                                               : (uint32_t)(((uint64_t)dt << TH_W_BITS) / ((uint64_t)tau + dt));
                }
                uint32_t w = st->wq28[c][k] < TH_W_ONE ? st->wq28[c][k] : TH_W_ONE;
                s += abbe_shr_round((int64_t)w * (u - s), TH_W_BITS);
            }
            st->sq[c][k] = s;
            acc += abbe_shr_round((int64_t)th->gain_q16[c][k] * s, TH_STATE_BITS);
        }
        int64_t y = abbe_shr_round(acc, 16u);
        if (y > th->limit[c] || y < -(int64_t)th->limit[c]) {
            y = y > 0 ? th->limit[c] : -(int64_t)th->limit[c];
            flags |= ABBE_THERMAL_F_LIMIT;
        }
        st->yq[c] = (int32_t)y;
        uint8_t out = th->output[c];
        if (out == ABBE_THERMAL_OUT_A || out == ABBE_THERMAL_OUT_B) {
            /* nrad x nm = 1e-9 nm; |.| <= 2^30 x 2^31 / 10^9 = 2.3e9 nm: beyond
             * int32 for a tilt near its cap on a tool offset over 2.1 m (both
             * accepted by the loader), so held to +/-INT32_MAX and flagged */
            const int64_t tip_cap = INT32_MAX;
            int64_t tip = th_div_round(y * th->tool_z_nm, 1000000000);
            if ((tip > tip_cap) || (tip < -tip_cap)) {
                tip = (tip > 0) ? tip_cap : -tip_cap;
                flags |= ABBE_THERMAL_F_LIMIT;
            }
            st->tipq[c] = (int32_t)(out == ABBE_THERMAL_OUT_A ? -tip : tip);
        } else {
            st->tipq[c] = (int32_t)y;
        }
    }
    st->input_fault = faults;
    st->since_update = 0u;
    st->gap = 0u;
    th_mix_q(st);
    st->flags = th_state_flags(st, flags);
    st->events |= st->flags;
    return ABBE_OK;
}

/* One fade step of every channel, the mix and the flags in one pass (HOLD
 * changes only at a sample). */
static inline void th_fade_q(abbe_thermal_state_t *st, uint32_t step)
{
    const abbe_thermal_model_t *th = st->model;
    int64_t out[3] = {0, 0, 0};
    unsigned fading = 0u;
    /*@ loop unroll ABBE_THERMAL_MAX_CHANNELS; */
    for (unsigned c = 0; c < th->n_channels; c++) {
        /* the weight and the step are both within [0, TH_FADE_ONE]: the sum and the
         * difference computed whole, then held to [0, TH_FADE_ONE] (the same values
         * as min(w + step, ONE) and max(w - step, 0), in a form whose bound the
         * proof sees without relating w to step) */
        uint32_t w = st->wq24[c] < TH_FADE_ONE ? st->wq24[c] : TH_FADE_ONE;
        if (st->ch_state[c] == TH_CH_RUN && !st->gap) {
            uint32_t up = w + step;
            w = up < TH_FADE_ONE ? up : TH_FADE_ONE;
            fading |= w < TH_FADE_ONE;
        } else {
            int64_t down = (int64_t)w - (int64_t)step;
            w = down > 0 ? (uint32_t)down : 0u;
            fading |= w > 0u;
        }
        st->wq24[c] = w;
        out[st->tip_axis[c]] += (int64_t)w * st->tipq[c];
    }
    for (unsigned a = 0; a < 3u; a++) {
        st->outq[a] = (int32_t)abbe_clamp_i64(abbe_shr_round(out[a], 24u), -INT32_MAX, INT32_MAX);
    }
    st->fading = (uint8_t)fading;
    st->flags = (st->flags & ~(ABBE_THERMAL_F_FADING | ABBE_THERMAL_F_GAP)) | (fading ? ABBE_THERMAL_F_FADING : 0u) |
                (st->gap ? ABBE_THERMAL_F_GAP : 0u);
}

/* a + b saturated to int32 (the overflow flag where the compiler gives it: an
 * add and a branch instead of a 64-bit sum and two compares on a Cortex-M3) */
static inline int32_t th_sat_add(int32_t a, int32_t b)
{
#if defined(__GNUC__) || defined(__clang__)
    int32_t r;
    if (__builtin_add_overflow(a, b, &r)) {
        return a < 0 ? INT32_MIN : INT32_MAX;
    }
    return r;
#else
    return (int32_t)abbe_clamp_i64((int64_t)a + b, INT32_MIN, INT32_MAX);
#endif
}

void abbe_thermal_apply_q(abbe_thermal_state_t *st, int32_t err_nm[3])
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
        th_fade_q(st, st->fade_step_q24);
    }
    /* saturating: the sum stays an int32 whatever the error it is added to */
    err_nm[0] = th_sat_add(err_nm[0], st->outq[0]);
    err_nm[1] = th_sat_add(err_nm[1], st->outq[1]);
    err_nm[2] = th_sat_add(err_nm[2], st->outq[2]);
}

void abbe_thermal_apply_ms_q(abbe_thermal_state_t *st, int32_t err_nm[3], uint32_t elapsed_ms)
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
        /* weight change elapsed / fade (Q24); the 64-bit division only while fading */
        uint32_t step = elapsed_ms >= th->fade_ms
                            ? TH_FADE_ONE
                            : (uint32_t)((((uint64_t)elapsed_ms << 24) + th->fade_ms / 2u) / th->fade_ms);
        th_fade_q(st, step);
    }
    err_nm[0] = th_sat_add(err_nm[0], st->outq[0]);
    err_nm[1] = th_sat_add(err_nm[1], st->outq[1]);
    err_nm[2] = th_sat_add(err_nm[2], st->outq[2]);
}

unsigned abbe_thermal_channels_q(const abbe_thermal_state_t *st, int32_t y[ABBE_THERMAL_MAX_CHANNELS])
{
    if (st == NULL || st->model == NULL || y == NULL) {
        return 0u;
    }
    for (unsigned c = 0; c < st->model->n_channels; c++) {
        y[c] = st->yq[c];
    }
    return st->model->n_channels;
}

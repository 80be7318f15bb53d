/* abbe: what the two thermal variants share (included by thermal_f32.c, thermal_q.c). */
#ifndef ABBE_THERMAL_COMMON_H
#define ABBE_THERMAL_COMMON_H
#include <string.h>

#include "abbe/thermal.h"

enum { TH_CH_OFF = 0, TH_CH_RUN = 1, TH_CH_HOLD = 2 };

/* Which tool-tip axis a channel's output moves: x, b -> X; y, a -> Y; z -> Z. */
static inline uint8_t th_tip_axis(uint8_t output)
{
    static const uint8_t axis[5] = {0u, 1u, 2u, 1u, 0u};
    return axis[output];
}

/* A state's common start: no channel running, weights 0, no flags. */
static inline void th_init_common(abbe_thermal_state_t *st, const abbe_thermal_model_t *th)
{
    memset(st, 0, sizeof *st);
    st->model = th;
    for (unsigned c = 0; c < th->n_channels; c++) {
        st->tip_axis[c] = th_tip_axis(th->output[c]);
    }
}

/* The channels' state machine for one sample (faults: inputs faulted now;
 * gap: the sample came late). faded_out(c): the channel's weight is 0.
 * Returns per channel what to do: 0 nothing (hold), 1 start (states = rises),
 * 2 step (one backward Euler step over its age). */
static inline unsigned th_channel_action(abbe_thermal_state_t *st, unsigned c, uint32_t faults, int gap,
                                         int faded_out)
{
    const abbe_thermal_model_t *th = st->model;
    uint32_t need = th->channel_inputs[c];
    int ok = (faults & need) == 0u && !gap && (st->seen & need) == need;
    switch (st->ch_state[c]) {
    case TH_CH_OFF:
        if (ok) {
            st->ch_state[c] = TH_CH_RUN;
            return 1u;
        }
        return 0u;
    case TH_CH_RUN:
        if (ok) {
            return 2u;
        }
        st->ch_state[c] = TH_CH_HOLD;
        return 0u;
    default: /* HOLD: back only once faded out, so the catch-up step cannot jump */
        if (ok && faded_out) {
            st->ch_state[c] = TH_CH_RUN;
            return 2u;
        }
        return 0u;
    }
}

/* Current flags after a sample or a fade step. */
static inline uint32_t th_state_flags(const abbe_thermal_state_t *st, uint32_t sample_flags)
{
    uint32_t f = sample_flags;
    for (unsigned c = 0; c < st->model->n_channels; c++) {
        if (st->ch_state[c] == TH_CH_HOLD) {
            f |= ABBE_THERMAL_F_HOLD;
        }
    }
    if (st->gap) {
        f |= ABBE_THERMAL_F_GAP;
    }
    if (st->fading) {
        f |= ABBE_THERMAL_F_FADING;
    }
    return f;
}
#endif

/* abbe Modbus port: the input registers, the thermal inputs and the
 * compensation cycle they trigger (docs/modbus-registers.md). */
#include <stddef.h>
#include <string.h>

#include "regs_internal.h"

abbe_comp_stats_t abbe_mb_stats_sum(const abbe_mb_regs_t *r)
{
    abbe_comp_stats_t s = abbe_comp_stats(&r->comp), b = r->stats_base;
    s.cycles += b.cycles;
    s.invalid_inputs += b.invalid_inputs;
    s.stale_events += b.stale_events;
    s.limit_trips += b.limit_trips;
    s.rate_limited += b.rate_limited;
    s.model_swaps += b.model_swaps;
    return s;
}

/* ---- the cycle -------------------------------------------------------------------- */

/* The thermal state of the table that runs next (started afresh for a new
 * table: it fades in after its first good sample); NULL without a block. */
static abbe_thermal_state_t *thermal_state(abbe_mb_regs_t *r)
{
    int8_t b = (int8_t)(r->pending >= 0 ? r->pending : r->running);
    if (b < 0 || b >= ABBE_MB_BANKS || r->thermal[b].n_channels == 0u) {
        r->th_bank = -1;
        return NULL;
    }
    if (b != r->th_bank) {
        (void)abbe_thermal_init_q(&r->th, &r->thermal[b], r->cycle_us);
        r->th_bank = b;
    }
    return &r->th;
}

static void compensation_cycle(abbe_mb_regs_t *r)
{
    abbe_comp_input_q_t in;
    uint8_t fresh = r->pos_written == 0x7u;
    memset(&in, 0, sizeof in);
    for (unsigned j = 0; j < ABBE_AXES; j++) {
        in.pos_nm[j] = r->pos_nm[j];
        in.temp_mdegc[j] = 10 * (int32_t)r->temp_cdegc[j];
        if (r->dir_source) {
            int32_t d = 0;
            if (fresh && r->have_last_pos) {
                d = r->pos_nm[j] > r->last_pos_nm[j] ? 1 : (r->pos_nm[j] < r->last_pos_nm[j] ? -1 : 0);
            }
            in.dir[j] = (int8_t)d;
        } else {
            in.dir[j] = (int8_t)r->dir[j];
        }
    }
    in.fresh = fresh;
    in.axis_fault_mask = (uint8_t)r->axis_fault;
    (void)abbe_comp_step_thermal_q(&r->comp, thermal_state(r), &in, &r->out); /* only fails for NULL pointers */
    if (fresh) {
        memcpy(r->last_pos_nm, r->pos_nm, sizeof r->last_pos_nm);
        r->have_last_pos = 1;
    }
    r->pos_written = 0;
    for (unsigned j = 0; j < ABBE_AXES; j++) {
        /* target = -sign * error, clamped to +/-INT32_MAX by the compensator;
         * INT32_MIN is still mapped, so the negation never overflows */
        const int32_t t = r->out.target_nm[j];
        const int32_t neg = t == INT32_MIN ? INT32_MAX : -t;
        r->err_nm[j] = r->comp_cfg.axis_sign[j] > 0 ? neg : t;
    }
    r->out_cycle = r->cycle_in;
    if (r->pending >= 0 && abbe_comp_model(&r->comp) == &r->slot[r->pending]) {
        r->running = r->pending;
        r->pending = -1;
        const abbe_model_t *m = &r->slot[r->running];
        abbe_mb_emit(r, ABBE_MB_EV_MODEL_SWAP, 0, 0, abbe_model_size(m), abbe_model_crc(m));
    }
}

int abbe_mb_write_inputs(abbe_mb_regs_t *r, uint16_t addr, uint16_t count, const uint16_t *v)
{
    int32_t pos[ABBE_AXES];
    int16_t dir[ABBE_AXES], temp[ABBE_AXES];
    uint16_t fault = r->axis_fault, cycle = r->cycle_in;
    uint8_t written = 0, trigger = 0;
    memcpy(pos, r->pos_nm, sizeof pos);
    memcpy(dir, r->dir, sizeof dir);
    memcpy(temp, r->temp_cdegc, sizeof temp);

    for (uint16_t i = 0; i < count; i++) {
        uint16_t a = (uint16_t)(addr + i);
        if (a < ABBE_MB_REG_IN_BASE || a >= ABBE_MB_REG_IN_BASE + ABBE_MB_IN_COUNT) {
            return ABBE_MB_EX_ILLEGAL_ADDRESS; /* not reached: the request is inside the block */
        }
        if (a < ABBE_MB_REG_IN_DIR_X) {
            unsigned j = (unsigned)(a - ABBE_MB_REG_IN_POS_X) / 2u;
            if (((a - ABBE_MB_REG_IN_POS_X) & 1u) == 0u) {
                pos[j] = abbe_mb_to_i32(abbe_mb_get32(r, &v[i]));
                written |= (uint8_t)(1u << j);
            }
        } else if (a <= ABBE_MB_REG_IN_DIR_Z) {
            int16_t d = abbe_mb_to_i16(v[i]);
            if (d < -1 || d > 1) {
                return ABBE_MB_EX_ILLEGAL_VALUE;
            }
            dir[a - ABBE_MB_REG_IN_DIR_X] = d;
        } else if (a <= ABBE_MB_REG_IN_TEMP_Z) {
            int16_t t = abbe_mb_to_i16(v[i]);
            if (t == ABBE_MB_TEMP_NO_READING) {
                continue; /* no reading: keep the axis' temperature */
            }
            if (t < ABBE_MB_TEMP_MIN_CDEGC || t > ABBE_MB_TEMP_MAX_CDEGC) {
                return ABBE_MB_EX_ILLEGAL_VALUE;
            }
            temp[a - ABBE_MB_REG_IN_TEMP_X] = t;
        } else if (a == ABBE_MB_REG_IN_AXIS_FAULT) {
            if (v[i] > 7u) {
                return ABBE_MB_EX_ILLEGAL_VALUE;
            }
            fault = v[i];
        } else {
            cycle = v[i];
            trigger = 1;
        }
    }
    memcpy(r->pos_nm, pos, sizeof pos);
    memcpy(r->dir, dir, sizeof dir);
    memcpy(r->temp_cdegc, temp, sizeof temp);
    r->axis_fault = fault;
    r->cycle_in = cycle;
    r->pos_written |= written;
    if (trigger) {
        compensation_cycle(r);
    }
    return 0;
}

/* IN_TH_*: every value is taken (the runtime judges the readings); the
 * reserved register must be 0, IN_TH_DT_MS 1 .. 2^31. */
int abbe_mb_write_thermal(abbe_mb_regs_t *r, uint16_t addr, uint16_t count, const uint16_t *v)
{
    int16_t in[ABBE_MB_TH_INPUTS];
    uint32_t dt = r->th_dt_ms;
    uint16_t echo = r->th_echo;
    uint8_t trigger = 0;
    memcpy(in, r->th_in, sizeof in);
    for (uint16_t i = 0; i < count; i++) {
        uint16_t a = (uint16_t)(addr + i);
        if (a < ABBE_MB_REG_TIN_BASE || a >= ABBE_MB_REG_TIN_BASE + ABBE_MB_TIN_COUNT) {
            return ABBE_MB_EX_ILLEGAL_ADDRESS; /* not reached: the request is inside the block */
        }
        if (a < ABBE_MB_REG_IN_TH_RESERVED) {
            in[a - ABBE_MB_REG_IN_TH_0] = abbe_mb_to_i16(v[i]);
        } else if (a == ABBE_MB_REG_IN_TH_RESERVED) {
            if (v[i] != 0u) {
                return ABBE_MB_EX_ILLEGAL_VALUE;
            }
        } else if (a == ABBE_MB_REG_IN_TH_DT_MS) {
            dt = abbe_mb_get32(r, &v[i]);
            if (dt < 1u || dt > 0x80000000u) {
                return ABBE_MB_EX_ILLEGAL_VALUE;
            }
        } else if (a == ABBE_MB_REG_IN_TH_SAMPLE) {
            echo = v[i];
            trigger = 1;
        }
    }
    memcpy(r->th_in, in, sizeof in);
    r->th_dt_ms = dt;
    r->th_echo = echo;
    abbe_thermal_state_t *th = trigger ? thermal_state(r) : NULL;
    const int8_t tb = r->th_bank; /* set by thermal_state: a bank when th is not NULL */
    if (th != NULL && tb >= 0 && tb < ABBE_MB_BANKS) {
        const abbe_thermal_model_t *tm = &r->thermal[tb];
        int32_t x[ABBE_MB_TH_INPUTS];
        uint32_t valid = 0;
        for (unsigned k = 0; k < ABBE_MB_TH_INPUTS; k++) {
            x[k] = tm->kind[k] == ABBE_THERMAL_SPEED ? in[k] : 10 * (int32_t)in[k]; /* rpm; m degC */
            valid |= in[k] != ABBE_MB_TEMP_NO_READING ? 1u << k : 0u;
        }
        (void)abbe_thermal_update_q(th, x, valid, dt);
        r->th_samples++;
    }
    return 0;
}

/* abbe Modbus port: the read path, each register block rendered from the
 * engine's state (docs/modbus-registers.md). */
#include <stddef.h>
#include <string.h>

#include "regs_internal.h"

static uint32_t model_crc_or_0(const abbe_model_t *m)
{
    return m != NULL ? abbe_model_crc(m) : 0u;
}

/* ---- rendering blocks for reads -------------------------------------------------- */

void abbe_mb_render(const abbe_mb_regs_t *r, int b, uint16_t *d)
{
    const abbe_model_t *m = abbe_comp_model(&r->comp);
    switch (b) {
    case BLK_ID:
        d[0] = ABBE_MB_MAGIC_HI;
        d[1] = ABBE_MB_MAGIC_LO;
        d[2] = ABBE_MB_REGMAP_VERSION;
        d[3] = ABBE_VERSION_MAJOR;
        d[4] = ABBE_VERSION_MINOR;
        d[5] = ABBE_VERSION_PATCH;
        d[6] = ABBE_TABLE_FORMAT_MAJOR;
        d[7] = ABBE_TABLE_FORMAT_MINOR;
        abbe_mb_put32(r, &d[8], ABBE_MB_SELFTEST_VALUE);
        abbe_mb_put32(r, &d[10], model_crc_or_0(m));
        abbe_mb_put32(r, &d[12], m != NULL ? abbe_model_size(m) : 0u);
        abbe_mb_put32(r, &d[14], r->pending >= 0 ? abbe_model_crc(&r->slot[r->pending]) : 0u);
        abbe_mb_put32(r, &d[16], (uint32_t)ABBE_MB_STAGING_MAX);
        d[18] = (uint16_t)(m != NULL ? abbe_model_features(m) : 0u);
        d[19] = r->max_clients;
        break;
    case BLK_ST: {
        abbe_comp_stats_t s = abbe_mb_stats_sum(r);
        d[0] = (uint16_t)r->out.state;
        d[1] = (uint16_t)r->out.flags;
        d[2] = r->clients;
        d[3] = r->owner != 0u ? ABBE_MB_UPLOAD_OPEN : ABBE_MB_UPLOAD_IDLE;
        abbe_mb_put32(r, &d[4], s.cycles);
        abbe_mb_put32(r, &d[6], r->requests);
        abbe_mb_put32(r, &d[8], r->exceptions);
        abbe_mb_put32(r, &d[10], r->uploads_ok);
        abbe_mb_put32(r, &d[12], r->uploads_rejected);
        abbe_mb_put32(r, &d[14], s.invalid_inputs);
        abbe_mb_put32(r, &d[16], s.stale_events);
        abbe_mb_put32(r, &d[18], s.limit_trips);
        abbe_mb_put32(r, &d[20], s.rate_limited);
        abbe_mb_put32(r, &d[22], s.model_swaps);
        abbe_mb_put32(r, &d[24], r->clients_refused);
        d[26] = r->last_exception;
        break;
    }
    case BLK_UP:
        d[0] = 0;
        d[1] = r->owner != 0u ? ABBE_MB_UPLOAD_OPEN : ABBE_MB_UPLOAD_IDLE;
        d[2] = r->session;
        d[3] = abbe_mb_from_i16(r->result);
        abbe_mb_put32(r, &d[4], r->filled);
        abbe_mb_put32(r, &d[6], r->commit_len);
        abbe_mb_put32(r, &d[8], r->commit_crc);
        abbe_mb_put32(r, &d[10], r->rx_crc);
        abbe_mb_put32(r, &d[12], r->model_crc);
        break;
    case BLK_IN:
        for (unsigned j = 0; j < ABBE_AXES; j++) {
            abbe_mb_put32(r, &d[2u * j], abbe_mb_from_i32(r->pos_nm[j]));
            d[6u + j] = abbe_mb_from_i16(r->dir[j]);
            d[9u + j] = abbe_mb_from_i16(r->temp_cdegc[j]);
        }
        d[12] = r->axis_fault;
        d[13] = r->cycle_in;
        break;
    case BLK_OUT:
        for (unsigned j = 0; j < ABBE_AXES; j++) {
            abbe_mb_put32(r, &d[2u * j], abbe_mb_from_i32(r->out.corr_nm[j]));
            abbe_mb_put32(r, &d[6u + 2u * j], abbe_mb_from_i32(r->err_nm[j]));
        }
        d[12] = (uint16_t)r->out.flags;
        d[13] = (uint16_t)r->out.state;
        d[14] = r->out_cycle;
        break;
    case BLK_TIN:
        for (unsigned k = 0; k < ABBE_MB_TH_INPUTS; k++) {
            d[k] = abbe_mb_from_i16(r->th_in[k]);
        }
        d[17] = 0;
        abbe_mb_put32(r, &d[18], r->th_dt_ms);
        d[20] = r->th_echo;
        break;
    case BLK_TOUT: {
        const int8_t tb = r->th_bank;
        const abbe_thermal_state_t *th = tb >= 0 && tb < ABBE_MB_BANKS ? &r->th : NULL;
        int32_t y[ABBE_THERMAL_MAX_CHANNELS] = {0, 0, 0, 0, 0};
        unsigned n = th != NULL ? abbe_thermal_channels_q(th, y) : 0u;
        d[0] = (uint16_t)abbe_thermal_flags(th);
        d[1] = tb >= 0 && tb < ABBE_MB_BANKS ? (uint16_t)((abbe_thermal_n_inputs(&r->thermal[tb]) << 8) | n) : 0u;
        abbe_mb_put32(r, &d[2], abbe_thermal_input_faults(th));
        abbe_mb_put32(r, &d[4], abbe_thermal_events(th));
        for (unsigned c = 0; c < ABBE_THERMAL_MAX_CHANNELS; c++) {
            abbe_mb_put32(r, &d[6u + 2u * c], abbe_mb_from_i32(y[c]));
        }
        d[16] = r->th_samples;
        d[17] = r->th_echo;
        break;
    }
    default: /* BLK_CT */
        d[0] = r->enabled;
        d[1] = 0;
        d[2] = r->word_order;
        d[3] = r->dir_source;
        d[4] = r->comp_cfg.fade_cycles;
        d[5] = r->comp_cfg.stale_cycles;
        for (unsigned j = 0; j < ABBE_AXES; j++) {
            abbe_mb_put32(r, &d[6u + 2u * j], abbe_mb_from_i32(r->comp_cfg.warn_nm[j]));
            abbe_mb_put32(r, &d[12u + 2u * j], abbe_mb_from_i32(r->comp_cfg.limit_nm[j]));
            abbe_mb_put32(r, &d[18u + 2u * j], abbe_mb_from_i32(r->comp_cfg.rate_nm_per_cycle[j]));
            d[24u + j] = abbe_mb_from_i16(r->comp_cfg.axis_sign[j]);
        }
        break;
    }
}

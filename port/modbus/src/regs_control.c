/* abbe Modbus port: the control registers (enable, reset, word order, limits,
 * signs), checked as a whole before any is applied (docs/modbus-registers.md). */
#include <stddef.h>
#include <string.h>

#include "regs_internal.h"

/* ---- control ------------------------------------------------------------------------ */

int abbe_mb_write_control(abbe_mb_regs_t *r, uint16_t addr, uint16_t count, const uint16_t *v)
{
    abbe_comp_config_t cfg = r->comp_cfg;
    int enable = -1, reset = 0, word_order = r->word_order, dir_source = r->dir_source;
    int limits = 0;

    for (uint16_t i = 0; i < count; i++) {
        uint16_t a = (uint16_t)(addr + i);
        uint16_t x = v[i];
        if (a < ABBE_MB_REG_CT_BASE || a >= ABBE_MB_REG_CT_BASE + ABBE_MB_CT_COUNT) {
            return ABBE_MB_EX_ILLEGAL_ADDRESS; /* not reached: the request is inside the block */
        }
        if (a >= ABBE_MB_CT_FIRST_LIMIT) {
            limits = 1;
        }
        if (a == ABBE_MB_REG_CT_ENABLE || a == ABBE_MB_REG_CT_RESET ||
            a == ABBE_MB_REG_CT_WORD_ORDER || a == ABBE_MB_REG_CT_DIR_SOURCE) {
            if (x > 1u) {
                return ABBE_MB_EX_ILLEGAL_VALUE;
            }
            if (a == ABBE_MB_REG_CT_ENABLE) {
                enable = x;
            } else if (a == ABBE_MB_REG_CT_RESET) {
                reset = x;
            } else if (a == ABBE_MB_REG_CT_WORD_ORDER) {
                word_order = x;
            } else {
                dir_source = x;
            }
        } else if (a == ABBE_MB_REG_CT_FADE_CYCLES) {
            cfg.fade_cycles = x;
        } else if (a == ABBE_MB_REG_CT_STALE_CYCLES) {
            cfg.stale_cycles = x;
        } else if (a >= ABBE_MB_REG_CT_WARN_X && a < ABBE_MB_REG_CT_SIGN_X) {
            unsigned k = (unsigned)(a - ABBE_MB_REG_CT_WARN_X);
            if ((k & 1u) == 0u) {
                int32_t val = abbe_mb_to_i32(abbe_mb_get32(r, &v[i]));
                unsigned j = (k / 2u) % ABBE_AXES;
                if (k < 6u) {
                    cfg.warn_nm[j] = val;
                } else if (k < 12u) {
                    cfg.limit_nm[j] = val;
                } else {
                    cfg.rate_nm_per_cycle[j] = val;
                }
            }
        } else {
            int16_t s = abbe_mb_to_i16(x);
            if (s != 1 && s != -1) {
                return ABBE_MB_EX_ILLEGAL_VALUE;
            }
            cfg.axis_sign[a - ABBE_MB_REG_CT_SIGN_X] = (int8_t)s;
        }
    }

    if (limits) {
        /* The compensator must be off with zero output: re-initialising it
         * with the new limits then cannot make a correction jump. A reset in
         * the same request comes first: it clears a latched fault and
         * disables, so "reset, limits, enable" works from FAULT too. */
        int idle = (reset || !r->enabled) && (reset || r->out.state == ABBE_COMP_OFF);
        for (unsigned j = 0; j < ABBE_AXES; j++) {
            idle = idle && r->out.corr_nm[j] == 0;
        }
        if (!idle) {
            return ABBE_MB_EX_ILLEGAL_FUNCTION;
        }
        abbe_comp_t probe;
        if (abbe_comp_init(&probe, &cfg, NULL) != ABBE_OK) {
            return ABBE_MB_EX_ILLEGAL_VALUE;
        }
    }

    /* Everything checked: apply (reset, limits, enable, settings). */
    if (reset) {
        (void)abbe_comp_reset(&r->comp);
        r->enabled = 0;
    }
    if (limits) {
        const abbe_model_t *running = abbe_comp_model(&r->comp);
        r->stats_base = abbe_mb_stats_sum(r);
        (void)abbe_comp_init(&r->comp, &cfg, running);
        if (r->pending >= 0) {
            (void)abbe_comp_swap_model(&r->comp, &r->slot[r->pending]);
        }
        r->comp_cfg = cfg;
    }
    if (enable == 1) {
        (void)abbe_comp_enable(&r->comp);
        r->enabled = 1;
    } else if (enable == 0) {
        (void)abbe_comp_disable(&r->comp);
        r->enabled = 0;
    }
    r->word_order = (uint8_t)word_order;
    r->dir_source = (uint8_t)dir_source;
    return 0;
}

/* End-to-end scenario shared by the TCP and RTU tests (scenario.h). */
#define _POSIX_C_SOURCE 200809L

#include "scenario.h"

#include <errno.h>
#include <stdio.h>
#include <string.h>

#include "abbe/modbus_regs.h"
#include "harness.h"

abbe_comp_config_t scn_config(void)
{
    abbe_comp_config_t c;
    memset(&c, 0, sizeof c);
    for (int j = 0; j < ABBE_AXES; j++) {
        c.warn_nm[j] = 400000000;    /* 0.4 m: the full golden table reaches mm */
        c.limit_nm[j] = 800000000;
        c.rate_nm_per_cycle[j] = 50000; /* 50 um/cycle: clips the fade-in of large tables */
        c.axis_sign[j] = (int8_t)(j == 1 ? -1 : 1);
    }
    c.fade_cycles = 5;
    c.stale_cycles = 3;
    return c;
}

int scn_configure(modbus_t *ctx, int wo)
{
    abbe_comp_config_t c = scn_config();
    uint16_t v[ABBE_MB_REG_CT_SIGN_Z - ABBE_MB_REG_CT_FADE_CYCLES + 1];
    v[0] = c.fade_cycles;
    v[1] = c.stale_cycles;
    for (int j = 0; j < ABBE_AXES; j++) {
        mbt_put32(&v[2 + 2 * j], (uint32_t)c.warn_nm[j], wo);
        mbt_put32(&v[8 + 2 * j], (uint32_t)c.limit_nm[j], wo);
        mbt_put32(&v[14 + 2 * j], (uint32_t)c.rate_nm_per_cycle[j], wo);
        v[20 + j] = (uint16_t)(c.axis_sign[j] < 0 ? 0xFFFFu : 1u);
    }
    int n = (int)(sizeof v / sizeof v[0]);
    return modbus_write_registers(ctx, ABBE_MB_REG_CT_FADE_CYCLES, n, v) == n ? 0 : -1;
}

int scn_upload(modbus_t *ctx, const uint8_t *blob, size_t size, int wo)
{
    abbe_model_t m;
    if (abbe_model_load(&m, blob, size) != ABBE_OK) {
        errno = EINVAL;
        return -1;
    }
    if (mbt_upload(ctx, blob, size, abbe_crc32(0, blob, size), MODBUS_MAX_WRITE_REGISTERS, wo) != 0) {
        return -1;
    }
    uint16_t up[ABBE_MB_UP_COUNT];
    if (modbus_read_registers(ctx, ABBE_MB_REG_UP_BASE, ABBE_MB_UP_COUNT, up) != ABBE_MB_UP_COUNT) {
        return -1;
    }
    uint32_t model_crc = mbt_get32(&up[ABBE_MB_REG_UP_MODEL_CRC - ABBE_MB_REG_UP_BASE], wo);
    uint32_t pending = 0;
    if (mbt_read32(ctx, ABBE_MB_REG_ID_PENDING_CRC, wo, &pending) != 0) {
        return -1;
    }
    if ((int16_t)up[ABBE_MB_REG_UP_RESULT - ABBE_MB_REG_UP_BASE] != ABBE_MB_UP_OK ||
        up[ABBE_MB_REG_UP_STATE - ABBE_MB_REG_UP_BASE] != ABBE_MB_UPLOAD_IDLE ||
        model_crc != abbe_model_crc(&m) || pending != model_crc) {
        errno = EPROTO;
        return -1;
    }
    return 0;
}

/* Positions: a triangle sweep with reversals for the first half, then small
 * steps around one point (partial backlash take-up), nm. */
static void trajectory(int k, int n, int32_t pos[ABBE_AXES])
{
    static const int32_t centre[ABBE_AXES] = {250000000, -200000000, -150000000};
    static const int32_t amp[ABBE_AXES] = {150000000, 120000000, 90000000};
    static const int period[ABBE_AXES] = {40, 56, 34};
    for (int j = 0; j < ABBE_AXES; j++) {
        if (k < n / 2) {
            int ph = k % period[j], half = period[j] / 2;
            int tri = ph < half ? ph : period[j] - ph; /* 0 .. half .. 0 */
            pos[j] = centre[j] - amp[j] + (int32_t)((int64_t)2 * amp[j] * tri / half);
        } else {
            int ph = k % 12;
            int tri = ph < 6 ? ph : 12 - ph;
            pos[j] = centre[j] + 30000 * tri * (j + 1);
        }
    }
}

int scn_stream_compare(modbus_t *ctx, const uint8_t *blob, size_t size, int wo, int ncycles,
                       int32_t *moved)
{
    abbe_comp_config_t cfg = scn_config();
    abbe_comp_t local;
    abbe_model_t slot;
    int32_t prev[ABBE_AXES] = {0, 0, 0};
    int mismatches = 0;

    *moved = 0;
    if (abbe_comp_init(&local, &cfg, NULL) != ABBE_OK ||
        abbe_comp_load_model(&local, &slot, blob, size) != ABBE_OK ||
        abbe_comp_enable(&local) != ABBE_OK) {
        return -1;
    }
    if (modbus_write_register(ctx, ABBE_MB_REG_CT_ENABLE, 1) != 1) {
        return -1;
    }
    for (int k = 0; k < ncycles; k++) {
        abbe_comp_input_q_t in;
        abbe_comp_output_t out;
        uint16_t w[ABBE_MB_IN_COUNT], r[ABBE_MB_OUT_COUNT];
        int32_t pos[ABBE_AXES];
        int stale = k >= 50 && k < 54; /* cycles without fresh positions */

        trajectory(k, ncycles, pos);
        memset(&in, 0, sizeof in);
        for (int j = 0; j < ABBE_AXES; j++) {
            in.pos_nm[j] = stale ? prev[j] : pos[j];
            in.dir[j] = (int8_t)(pos[j] > prev[j] ? 1 : (pos[j] < prev[j] ? -1 : 0));
            int16_t t_cdeg = (int16_t)(1900 + (k * 7 + 40 * j) % 500);
            in.temp_mdegc[j] = 10 * t_cdeg;
            mbt_put32(&w[2 * j], (uint32_t)in.pos_nm[j], wo);
            w[6 + j] = (uint16_t)(in.dir[j] < 0 ? 0xFFFFu : (uint16_t)in.dir[j]);
            w[9 + j] = (uint16_t)t_cdeg;
        }
        in.axis_fault_mask = (uint8_t)(k >= 30 && k < 40 ? 0x2u : 0u);
        in.fresh = (uint8_t)!stale;
        w[12] = in.axis_fault_mask;
        w[13] = (uint16_t)k;
        int rc;
        if (stale) {
            /* dir, temp and fault as before: write them, not the positions */
            rc = modbus_write_and_read_registers(ctx, ABBE_MB_REG_IN_DIR_X, 8, &w[6],
                                                 ABBE_MB_REG_OUT_BASE, ABBE_MB_OUT_COUNT, r);
        } else {
            rc = modbus_write_and_read_registers(ctx, ABBE_MB_REG_IN_BASE, ABBE_MB_IN_COUNT, w,
                                                 ABBE_MB_REG_OUT_BASE, ABBE_MB_OUT_COUNT, r);
        }
        if (rc != ABBE_MB_OUT_COUNT) {
            return -1;
        }
        if (!stale) {
            memcpy(prev, pos, sizeof prev);
        }
        (void)abbe_comp_step_q(&local, &in, &out);

        int bad = r[ABBE_MB_REG_OUT_CYCLE - ABBE_MB_REG_OUT_BASE] != (uint16_t)k ||
                  r[ABBE_MB_REG_OUT_FLAGS - ABBE_MB_REG_OUT_BASE] != (uint16_t)out.flags ||
                  r[ABBE_MB_REG_OUT_STATE - ABBE_MB_REG_OUT_BASE] != (uint16_t)out.state;
        for (int j = 0; j < ABBE_AXES; j++) {
            int32_t corr = (int32_t)mbt_get32(&r[2 * j], wo);
            int32_t err = (int32_t)mbt_get32(&r[6 + 2 * j], wo);
            int32_t want_err = cfg.axis_sign[j] > 0 ? -out.target_nm[j] : out.target_nm[j];
            bad |= corr != out.corr_nm[j] || err != want_err;
            int32_t mag = corr < 0 ? -corr : corr;
            *moved = mag > *moved ? mag : *moved;
        }
        if (bad && mismatches++ < 5) {
            fprintf(stderr, "cycle %d: server corr %d %d %d flags 0x%x, local %d %d %d flags 0x%x\n", k,
                    (int)mbt_get32(&r[0], wo), (int)mbt_get32(&r[2], wo), (int)mbt_get32(&r[4], wo),
                    r[ABBE_MB_REG_OUT_FLAGS - ABBE_MB_REG_OUT_BASE], out.corr_nm[0], out.corr_nm[1],
                    out.corr_nm[2], out.flags);
        }
    }

    /* Leave the compensator off with zero output (so limits may change). */
    if (modbus_write_register(ctx, ABBE_MB_REG_CT_ENABLE, 0) != 1) {
        return -1;
    }
    for (int k = 0; k < 10000; k++) {
        uint16_t c = (uint16_t)(60000 + k), r[ABBE_MB_OUT_COUNT];
        if (modbus_write_and_read_registers(ctx, ABBE_MB_REG_IN_CYCLE, 1, &c, ABBE_MB_REG_OUT_BASE,
                                            ABBE_MB_OUT_COUNT, r) != ABBE_MB_OUT_COUNT) {
            return -1;
        }
        if (r[0] == 0 && r[1] == 0 && r[2] == 0 && r[3] == 0 && r[4] == 0 && r[5] == 0 &&
            r[ABBE_MB_REG_OUT_STATE - ABBE_MB_REG_OUT_BASE] == ABBE_COMP_OFF) {
            break;
        }
    }
    return mismatches;
}

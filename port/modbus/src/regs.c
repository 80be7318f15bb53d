/* abbe Modbus port: register map engine, its public API (docs/modbus-registers.md).
 *
 * Tables live in three banks: the running one, the one queued for the next
 * cycle, and the staging bank the host writes into. A commit validates the
 * staging bank in place and queues it (abbe_comp_load_model), so the running
 * model is never touched by an upload and the swap happens at a cycle
 * boundary, inside abbe_comp_step_q(). Every request is checked as a whole
 * before anything changes.
 *
 * The engine is split by concern: this file (configuration, request
 * checks and dispatch, session ticks, counters), regs_render.c (the read path),
 * regs_upload.c (the table upload session), regs_cycle.c (the inputs, the
 * thermal inputs and the compensation cycle), regs_control.c (the settings).
 */
#include <stddef.h>
#include <string.h>

#include "regs_internal.h"

/* abbe_model_load() reads the coefficients in place and refuses a blob that is
 * not 4-byte aligned (ABBE_E_ALIGN): every bank must be, and is, since the
 * struct is aligned for its uint32_t members. */
typedef char abbe_mb_bank_align_check[(offsetof(abbe_mb_regs_t, bank) % 4u == 0u &&
                                       ABBE_MB_STAGING_MAX % 4 == 0) ? 1 : -1];

typedef struct {
    uint16_t base;
    uint16_t count;
} block_t;

static const block_t abbe_mb_blocks[BLK_STAGING] = {
    {ABBE_MB_REG_ID_BASE, ABBE_MB_ID_COUNT}, {ABBE_MB_REG_ST_BASE, ABBE_MB_ST_COUNT},
    {ABBE_MB_REG_UP_BASE, ABBE_MB_UP_COUNT}, {ABBE_MB_REG_IN_BASE, ABBE_MB_IN_COUNT},
    {ABBE_MB_REG_OUT_BASE, ABBE_MB_OUT_COUNT}, {ABBE_MB_REG_CT_BASE, ABBE_MB_CT_COUNT},
    {ABBE_MB_REG_TIN_BASE, ABBE_MB_TIN_COUNT}, {ABBE_MB_REG_TOUT_BASE, ABBE_MB_TOUT_COUNT},
};

int abbe_mb_find_block(uint16_t addr, uint16_t count)
{
    uint32_t end = (uint32_t)addr + count;
    for (int b = 0; b < BLK_STAGING; b++) {
        const block_t *k = &abbe_mb_blocks[b];
        if (addr >= k->base && end <= (uint32_t)k->base + k->count) {
            return b;
        }
    }
    if (addr >= ABBE_MB_REG_STAGING && end <= ABBE_MB_REG_STAGING + ABBE_MB_STAGING_REGS) {
        return BLK_STAGING;
    }
    return BLK_NONE;
}

int abbe_mb_pair_second(uint16_t addr)
{
    if (addr > ABBE_MB_REG_IN_POS_X && addr <= ABBE_MB_REG_IN_POS_Z + 1u) {
        return ((addr - ABBE_MB_REG_IN_POS_X) & 1u) != 0u;
    }
    if (addr > ABBE_MB_REG_CT_WARN_X && addr <= ABBE_MB_REG_CT_RATE_Z + 1u) {
        return ((addr - ABBE_MB_REG_CT_WARN_X) & 1u) != 0u;
    }
    if (addr == ABBE_MB_REG_IN_TH_DT_MS + 1u) {
        return 1;
    }
    return 0;
}

/* ---- public API ------------------------------------------------------------------------ */

void abbe_mb_regs_default_config(abbe_mb_regs_config_t *cfg)
{
    if (cfg == NULL) {
        return;
    }
    memset(cfg, 0, sizeof *cfg);
    for (unsigned j = 0; j < ABBE_AXES; j++) {
        cfg->comp.warn_nm[j] = 100000;
        cfg->comp.limit_nm[j] = 500000;
        cfg->comp.rate_nm_per_cycle[j] = 1000;
        cfg->comp.axis_sign[j] = 1;
    }
    cfg->comp.fade_cycles = 1000;
    cfg->comp.stale_cycles = 10;
    cfg->word_order = ABBE_MB_WORD_ORDER_HIGH_FIRST;
    cfg->dir_source = 0;
    cfg->max_clients = 1;
    cfg->upload_timeout_ms = 10000;
    cfg->cycle_us = 1000;
}

abbe_status_t abbe_mb_regs_init(abbe_mb_regs_t *r, const abbe_mb_regs_config_t *cfg,
                                const void *blob, size_t size)
{
    if (r == NULL || cfg == NULL || cfg->word_order > 1u || cfg->dir_source > 1u ||
        size > (size_t)ABBE_MB_STAGING_MAX || (blob == NULL && size != 0u)) {
        return ABBE_E_ARG;
    }
    abbe_comp_t probe;
    if (abbe_comp_init(&probe, &cfg->comp, NULL) != ABBE_OK) {
        return ABBE_E_ARG;
    }
    memset(r, 0, sizeof *r);
    r->comp_cfg = cfg->comp;
    r->word_order = cfg->word_order;
    r->dir_source = cfg->dir_source;
    r->max_clients = cfg->max_clients;
    r->upload_timeout_ms = cfg->upload_timeout_ms;
    r->running = r->pending = r->staging = -1;
    r->th_bank = -1;
    r->cycle_us = cfg->cycle_us != 0u ? cfg->cycle_us : 1000u;
    r->th_dt_ms = 1000u;
    for (unsigned k = 0; k < ABBE_MB_TH_INPUTS; k++) {
        r->th_in[k] = ABBE_MB_TEMP_NO_READING;
    }
    for (unsigned j = 0; j < ABBE_AXES; j++) {
        r->temp_cdegc[j] = 2000; /* 20 degC, the ISO 1 reference, until the controller writes */
    }
    (void)abbe_comp_init(&r->comp, &r->comp_cfg, NULL);
    r->out.state = ABBE_COMP_OFF;
    if (blob == NULL) {
        return ABBE_OK;
    }
    memcpy(r->bank[0], blob, size);
    abbe_status_t st = abbe_thermal_load(&r->slot[0], &r->thermal[0], r->bank[0], size);
    if (st != ABBE_OK) {
        memset(r->bank[0], 0, sizeof r->bank[0]);
        return st;
    }
    (void)abbe_comp_init(&r->comp, &r->comp_cfg, &r->slot[0]);
    r->running = 0;
    r->model_crc = abbe_model_crc(&r->slot[0]);
    return ABBE_OK;
}

int abbe_mb_regs_check_read(const abbe_mb_regs_t *r, uint32_t conn, uint16_t addr, uint16_t count)
{
    if (r == NULL) {
        return ABBE_MB_EX_DEVICE_FAILURE;
    }
    if (count < 1u || count > ABBE_MB_MAX_READ) {
        return ABBE_MB_EX_ILLEGAL_VALUE;
    }
    int b = abbe_mb_find_block(addr, count);
    if (b == BLK_NONE) {
        return ABBE_MB_EX_ILLEGAL_ADDRESS;
    }
    if (b == BLK_STAGING) {
        return abbe_mb_session_check(r, conn);
    }
    return 0;
}

int abbe_mb_regs_read(abbe_mb_regs_t *r, uint32_t conn, uint16_t addr, uint16_t count,
                      uint16_t *dst)
{
    int ex = abbe_mb_regs_check_read(r, conn, addr, count);
    if (ex != 0 || dst == NULL) {
        return ex != 0 ? ex : ABBE_MB_EX_DEVICE_FAILURE;
    }
    int b = abbe_mb_find_block(addr, count);
    /* The index checks in the two copies below never fail (find_block keeps
     * [addr, addr + count) inside the block; an open session has its bank):
     * they state it where the copy is, so the proof (docs/proofs.md) needs no
     * relation between addr, count and the block. */
    if (b == BLK_STAGING) {
        const int8_t s = r->staging;
        const uint32_t off = 2u * (uint32_t)(addr - ABBE_MB_REG_STAGING);
        if (s < 0 || s >= ABBE_MB_BANKS) {
            return ABBE_MB_EX_DEVICE_FAILURE;
        }
        for (uint16_t i = 0; i < count; i++) {
            const uint32_t k = off + 2u * (uint32_t)i;
            if (k + 1u >= (uint32_t)ABBE_MB_STAGING_MAX) {
                return ABBE_MB_EX_DEVICE_FAILURE;
            }
            dst[i] = (uint16_t)(((unsigned)r->bank[s][k] << 8) | r->bank[s][k + 1u]);
        }
        r->last_activity_ms = r->now_ms;
        return 0;
    }
    if (b < 0 || b >= BLK_STAGING) {
        return ABBE_MB_EX_DEVICE_FAILURE;
    }
    uint16_t buf[ABBE_MB_BLOCK_MAX];
    memset(buf, 0, sizeof buf);
    abbe_mb_render(r, b, buf);
    const uint32_t first = (uint32_t)addr - abbe_mb_blocks[b].base;
    for (uint16_t i = 0; i < count; i++) {
        const uint32_t k = first + i;
        if (k >= ABBE_MB_BLOCK_MAX) {
            return ABBE_MB_EX_DEVICE_FAILURE;
        }
        dst[i] = buf[k];
    }
    return 0;
}

int abbe_mb_regs_write(abbe_mb_regs_t *r, uint32_t conn, uint16_t addr, uint16_t count,
                       const uint8_t *values_be)
{
    if (r == NULL || values_be == NULL) {
        return ABBE_MB_EX_DEVICE_FAILURE;
    }
    if (count < 1u || count > ABBE_MB_MAX_WRITE) {
        return ABBE_MB_EX_ILLEGAL_VALUE;
    }
    int b = abbe_mb_find_block(addr, count);
    if (b == BLK_STAGING) {
        return abbe_mb_write_staging(r, conn, addr, count, values_be);
    }
    if (b != BLK_UP && b != BLK_IN && b != BLK_CT && b != BLK_TIN) {
        return ABBE_MB_EX_ILLEGAL_ADDRESS; /* unmapped or read only */
    }
    if (abbe_mb_pair_second(addr) || abbe_mb_pair_second((uint16_t)(addr + count))) {
        return ABBE_MB_EX_ILLEGAL_ADDRESS; /* half of a 32-bit value */
    }
    /* one register more than a request carries, all zero: the 32-bit reads
     * (abbe_mb_get32) take v[i + 1] where v[i] starts a pair, and the pair
     * checks above make it a written one */
    uint16_t v[ABBE_MB_MAX_WRITE + 1u];
    memset(v, 0, sizeof v);
    for (uint16_t i = 0; i < count; i++) {
        v[i] = (uint16_t)(((unsigned)values_be[2u * i] << 8) | values_be[2u * i + 1u]);
    }
    if (b == BLK_UP) {
        if (r->owner == conn) {
            r->last_activity_ms = r->now_ms;
        }
        return abbe_mb_write_upload(r, conn, addr, count, v);
    }
    if (b == BLK_IN) {
        return abbe_mb_write_inputs(r, addr, count, v);
    }
    if (b == BLK_TIN) {
        return abbe_mb_write_thermal(r, addr, count, v);
    }
    return abbe_mb_write_control(r, addr, count, v);
}

void abbe_mb_regs_disconnect(abbe_mb_regs_t *r, uint32_t conn)
{
    if (r != NULL && conn != 0u && r->owner == conn) {
        abbe_mb_session_close(r, ABBE_MB_UP_DISCONNECTED);
    }
}

void abbe_mb_regs_tick(abbe_mb_regs_t *r, uint32_t now_ms)
{
    if (r == NULL) {
        return;
    }
    r->now_ms = now_ms;
    if (r->owner != 0u && r->upload_timeout_ms != 0u &&
        (uint32_t)(now_ms - r->last_activity_ms) >= r->upload_timeout_ms) {
        abbe_mb_session_close(r, ABBE_MB_UP_TIMEOUT);
    }
}

void abbe_mb_regs_count_request(abbe_mb_regs_t *r, uint8_t function, int exception)
{
    if (r == NULL) {
        return;
    }
    if (exception == 0) {
        r->requests++;
    } else {
        r->exceptions++;
        r->last_exception = (uint16_t)(((unsigned)function << 8) | ((unsigned)exception & 0xFFu));
    }
}

void abbe_mb_regs_set_clients(abbe_mb_regs_t *r, uint16_t open, uint32_t refused)
{
    if (r != NULL) {
        r->clients = open;
        r->clients_refused = refused;
    }
}

void abbe_mb_regs_set_event_hook(abbe_mb_regs_t *r, abbe_mb_event_fn fn, void *ctx)
{
    if (r != NULL) {
        r->event_fn = fn;
        r->event_ctx = ctx;
    }
}

const abbe_comp_t *abbe_mb_regs_comp(const abbe_mb_regs_t *r)
{
    return r != NULL ? &r->comp : NULL;
}

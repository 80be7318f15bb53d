/* abbe Modbus port: the table upload session (begin, staged chunks, commit,
 * abort, close) over three banks (docs/modbus-registers.md). */
#include <stddef.h>
#include <string.h>

#include "regs_internal.h"

static int8_t free_bank(const abbe_mb_regs_t *r)
{
    for (int8_t i = 0; i < ABBE_MB_BANKS; i++) {
        if (i != r->running && i != r->pending) {
            return i;
        }
    }
    return -1; /* not reached: three banks, at most two in use */
}

/* ---- upload session ------------------------------------------------------------ */

void abbe_mb_emit(const abbe_mb_regs_t *r, abbe_mb_event_kind_t kind, uint32_t conn, int16_t result,
                 uint32_t size, uint32_t crc)
{
    if (r->event_fn == NULL) {
        return;
    }
    abbe_mb_event_t ev;
    memset(&ev, 0, sizeof ev);
    ev.kind = kind;
    ev.conn = conn;
    ev.owner = r->owner;
    ev.session = r->session;
    ev.result = result;
    ev.cycle = r->cycle_in;
    ev.size = size;
    ev.crc = crc;
    r->event_fn(r->event_ctx, &ev);
}

void abbe_mb_session_close(abbe_mb_regs_t *r, int16_t result)
{
    uint32_t owner = r->owner;
    uint32_t size = result == ABBE_MB_UP_OK ? r->commit_len : 0u;
    uint32_t crc = result == ABBE_MB_UP_OK ? r->model_crc : 0u;
    r->owner = 0;
    r->staging = -1;
    r->filled = 0;
    r->result = result;
    if (result != ABBE_MB_UP_OK) {
        r->uploads_rejected++;
    }
    abbe_mb_emit(r, ABBE_MB_EV_UPLOAD_END, owner, result, size, crc);
}

/* No session: wrong state. Someone else's: busy. */
int abbe_mb_session_check(const abbe_mb_regs_t *r, uint32_t conn)
{
    if (r->owner == 0u) {
        return ABBE_MB_EX_ILLEGAL_FUNCTION;
    }
    return r->owner == conn ? 0 : ABBE_MB_EX_BUSY;
}

static int upload_begin(abbe_mb_regs_t *r, uint32_t conn)
{
    if (r->owner != 0u && r->owner != conn) {
        r->uploads_rejected++;
        abbe_mb_emit(r, ABBE_MB_EV_UPLOAD_BUSY, conn, 0, 0, 0);
        return ABBE_MB_EX_BUSY;
    }
    if (r->owner == conn) {
        abbe_mb_session_close(r, ABBE_MB_UP_ABORTED);
    }
    const int8_t s = free_bank(r);
    if (s < 0 || s >= ABBE_MB_BANKS) {
        return ABBE_MB_EX_DEVICE_FAILURE; /* not reached: three banks, at most two in use */
    }
    r->staging = s;
    memset(r->bank[s], 0, sizeof r->bank[0]);
    r->owner = conn;
    r->filled = 0;
    r->session = (uint16_t)(r->session == UINT16_MAX ? 1u : r->session + 1u);
    r->result = ABBE_MB_UP_NONE;
    r->last_activity_ms = r->now_ms;
    abbe_mb_emit(r, ABBE_MB_EV_UPLOAD_BEGIN, conn, 0, 0, 0);
    return 0;
}

static int upload_commit(abbe_mb_regs_t *r, uint32_t conn, uint32_t len, uint32_t crc)
{
    int ex = abbe_mb_session_check(r, conn);
    if (ex != 0) {
        return ex;
    }
    r->commit_len = len;
    r->commit_crc = crc;
    r->rx_crc = 0;
    if (len == 0u || len > (uint32_t)ABBE_MB_STAGING_MAX) {
        abbe_mb_session_close(r, ABBE_MB_UP_LENGTH);
        return ABBE_MB_EX_ILLEGAL_VALUE;
    }
    if (len > r->filled) {
        abbe_mb_session_close(r, ABBE_MB_UP_INCOMPLETE);
        return ABBE_MB_EX_ILLEGAL_VALUE;
    }
    const int8_t s = r->staging;
    if (s < 0 || s >= ABBE_MB_BANKS) {
        return ABBE_MB_EX_DEVICE_FAILURE; /* not reached: an open session has its bank */
    }
    /* the CRC and the loader read bank[s][0 .. len): inside the bank, which
     * Eva checks here (its memory checks alone see the whole struct) */
    //@ assert staged_inside: 0 < len <= sizeof(r->bank[0]);
    r->rx_crc = abbe_crc32(0u, r->bank[s], len);
    if (r->rx_crc != crc) {
        abbe_mb_session_close(r, ABBE_MB_UP_CRC_MISMATCH);
        return ABBE_MB_EX_ILLEGAL_VALUE;
    }
    /* abbe_thermal_load: every check of abbe_model_load, and format 1.3's thermal block */
    abbe_status_t st = abbe_thermal_load(&r->slot[s], &r->thermal[s], r->bank[s], len);
    if (st == ABBE_OK) {
        st = abbe_comp_swap_model(&r->comp, &r->slot[s]);
    }
    if (st != ABBE_OK) {
        abbe_mb_session_close(r, (int16_t)st);
        return ABBE_MB_EX_ILLEGAL_VALUE;
    }
    r->pending = s;
    r->model_crc = abbe_model_crc(&r->slot[s]);
    r->uploads_ok++;
    abbe_mb_session_close(r, ABBE_MB_UP_OK);
    return 0;
}

int abbe_mb_write_upload(abbe_mb_regs_t *r, uint32_t conn, uint16_t addr, uint16_t count,
                        const uint16_t *v)
{
    if (addr == ABBE_MB_REG_UP_CMD && count == 1u) {
        if (v[0] == ABBE_MB_UP_CMD_BEGIN) {
            return upload_begin(r, conn);
        }
        if (v[0] == ABBE_MB_UP_CMD_ABORT) {
            int ex = abbe_mb_session_check(r, conn);
            if (ex == 0) {
                abbe_mb_session_close(r, ABBE_MB_UP_ABORTED);
            }
            return ex;
        }
        return ABBE_MB_EX_ILLEGAL_VALUE;
    }
    if (addr == ABBE_MB_REG_UP_COMMIT && count == 4u) {
        return upload_commit(r, conn, abbe_mb_get32(r, &v[0]), abbe_mb_get32(r, &v[2]));
    }
    return ABBE_MB_EX_ILLEGAL_ADDRESS;
}

int abbe_mb_write_staging(abbe_mb_regs_t *r, uint32_t conn, uint16_t addr, uint16_t count,
                         const uint8_t *values_be)
{
    int ex = abbe_mb_session_check(r, conn);
    if (ex != 0) {
        return ex;
    }
    const int8_t s = r->staging;
    const uint32_t off = 2u * (uint32_t)(addr - ABBE_MB_REG_STAGING);
    const uint32_t end = off + 2u * (uint32_t)count;
    if (off > r->filled) {
        return ABBE_MB_EX_ILLEGAL_ADDRESS; /* would leave a gap: chunks go in order */
    }
    /* not reached (an open session has its bank; find_block keeps the chunk
     * inside the staging registers): stated here for the proof */
    if (s < 0 || s >= ABBE_MB_BANKS || end > (uint32_t)ABBE_MB_STAGING_MAX) {
        return ABBE_MB_EX_DEVICE_FAILURE;
    }
    for (uint32_t i = 0; i < 2u * (uint32_t)count; i++) {
        const uint32_t k = off + i;
        if (k >= (uint32_t)ABBE_MB_STAGING_MAX) {
            return ABBE_MB_EX_DEVICE_FAILURE; /* not reached: end is inside */
        }
        r->bank[s][k] = values_be[i];
    }
    if (end > r->filled) {
        r->filled = end;
    }
    r->last_activity_ms = r->now_ms;
    return 0;
}

/* abbe Modbus port: what the register map engine's files share (regs.c,
 * regs_render.c, regs_upload.c, regs_cycle.c, regs_control.c); not installed.
 * The request checks of regs.c run before any of these: a write reaches
 * them whole inside one block, 1..ABBE_MB_MAX_WRITE registers, no 32-bit
 * value cut in half. */
#ifndef ABBE_MB_REGS_INTERNAL_H
#define ABBE_MB_REGS_INTERNAL_H

#include <stdint.h>

#include "abbe/modbus_port.h"

#define ABBE_MB_STAGING_REGS ((uint32_t)ABBE_MB_STAGING_MAX / 2u)
#define ABBE_MB_MAX_READ 125u
#define ABBE_MB_MAX_WRITE 123u

/* The register blocks (docs/modbus-registers.md), in abbe_mb_blocks' order. */
enum { BLK_ID, BLK_ST, BLK_UP, BLK_IN, BLK_OUT, BLK_CT, BLK_TIN, BLK_TOUT, BLK_STAGING, BLK_NONE };

/* The largest block, for the render buffer. */
#define ABBE_MB_BLOCK_MAX 32u

/* ---- 32-bit values in two registers, signed values as register bits ---------- */

static inline void abbe_mb_put32(const abbe_mb_regs_t *r, uint16_t *dst, uint32_t v)
{
    uint16_t hi = (uint16_t)(v >> 16), lo = (uint16_t)(v & 0xFFFFu);
    dst[0] = r->word_order == ABBE_MB_WORD_ORDER_LOW_FIRST ? lo : hi;
    dst[1] = r->word_order == ABBE_MB_WORD_ORDER_LOW_FIRST ? hi : lo;
}

/* src[0] and src[1] are both written: abbe_mb_regs_write refuses a write that
 * starts or ends inside a pair (abbe_mb_pair_second), which clang-analyzer does
 * not follow into the write_* functions (docs/misra.md). */
static inline uint32_t abbe_mb_get32(const abbe_mb_regs_t *r, const uint16_t *src)
{
    if (r->word_order == ABBE_MB_WORD_ORDER_LOW_FIRST) {
        return ((uint32_t)src[1] << 16) | src[0]; /* NOLINT(clang-analyzer-core.UndefinedBinaryOperatorResult) */
    }
    return ((uint32_t)src[0] << 16) | src[1]; /* NOLINT(clang-analyzer-core.UndefinedBinaryOperatorResult) */
}

static inline uint32_t abbe_mb_from_i32(int32_t v)
{
    return (uint32_t)v; /* two's complement bit pattern, defined for all values */
}

static inline int32_t abbe_mb_to_i32(uint32_t v)
{
    return v <= (uint32_t)INT32_MAX ? (int32_t)v : (int32_t)(v - 0x80000000u) + INT32_MIN;
}

static inline int16_t abbe_mb_to_i16(uint16_t v)
{
    /* NOLINTNEXTLINE(bugprone-narrowing-conversions): both branches are in int16_t range */
    return v <= (uint16_t)INT16_MAX ? (int16_t)v : (int16_t)((int32_t)v - 65536);
}

static inline uint16_t abbe_mb_from_i16(int16_t v)
{
    return (uint16_t)(v < 0 ? (int32_t)v + 65536 : (int32_t)v);
}

/* ---- regs.c: the map -------------------------------------------------------------- */

/* Block holding all of [addr, addr + count), or BLK_NONE. */
int abbe_mb_find_block(uint16_t addr, uint16_t count);
/* Is addr the second register of a 32-bit value in a writable block? */
int abbe_mb_pair_second(uint16_t addr);

/* ---- regs_render.c: the read path ------------------------------------------------- */

/* Block b (not BLK_STAGING, not BLK_NONE) into d[0 .. ABBE_MB_BLOCK_MAX). */
void abbe_mb_render(const abbe_mb_regs_t *r, int b, uint16_t *d);

/* ---- regs_upload.c: the upload session -------------------------------------------- */

void abbe_mb_emit(const abbe_mb_regs_t *r, abbe_mb_event_kind_t kind, uint32_t conn, int16_t result,
                  uint32_t size, uint32_t crc);
void abbe_mb_session_close(abbe_mb_regs_t *r, int16_t result);
/* 0 for the session's owner; no session: wrong state; someone else's: busy. */
int abbe_mb_session_check(const abbe_mb_regs_t *r, uint32_t conn);
/* UP_CMD / UP_COMMIT; v: the request's registers. */
int abbe_mb_write_upload(abbe_mb_regs_t *r, uint32_t conn, uint16_t addr, uint16_t count,
                         const uint16_t *v);
/* A chunk of the staged table, big-endian register bytes. */
int abbe_mb_write_staging(abbe_mb_regs_t *r, uint32_t conn, uint16_t addr, uint16_t count,
                          const uint8_t *values_be);

/* ---- regs_cycle.c: inputs, thermal inputs, the cycle ------------------------------ */

/* The compensator's counters since init, across re-initialisations. */
abbe_comp_stats_t abbe_mb_stats_sum(const abbe_mb_regs_t *r);
int abbe_mb_write_inputs(abbe_mb_regs_t *r, uint16_t addr, uint16_t count, const uint16_t *v);
int abbe_mb_write_thermal(abbe_mb_regs_t *r, uint16_t addr, uint16_t count, const uint16_t *v);

/* ---- regs_control.c: the settings ------------------------------------------------- */

int abbe_mb_write_control(abbe_mb_regs_t *r, uint16_t addr, uint16_t count, const uint16_t *v);

#endif

/* thermal_stuck.h: a stuck sensor for the ports' tests (hand-written, not generated).
 *
 * The golden format 1.3 table (golden_thermal.*) with the stuck check switched
 * on for one input (table block input byte 1 = stuck minutes, bytes 2-3 = the
 * stuck resolution in milli-units; docs/table-format.md), and the reading that
 * input gets in the ports' stuck tests: a ramp of ABBE_STUCK_RAMP_MILLI per
 * sample, then held exactly constant (a frozen converter), then the ramp again.
 * The golden inputs themselves are not used for it: near their sine's turning
 * points they may sit within the resolution for a while. */
#ifndef ABBE_THERMAL_STUCK_H
#define ABBE_THERMAL_STUCK_H

#include <stddef.h>
#include <stdint.h>
#include <string.h>

#include "abbe/model.h"
#include "golden_thermal.h"

#define ABBE_STUCK_INPUT 5u        /* a temperature some channels read and others do not */
#define ABBE_STUCK_MIN 2u          /* the stuck time: 2 min */
#define ABBE_STUCK_RES_MILLI 20u   /* still = within 0.02 K of the anchor */
#define ABBE_STUCK_RAMP_MILLI 50   /* the moving sensor: 0.05 K per sample (> the resolution) */

static inline uint32_t abbe_stuck_get_u32(const uint8_t *p)
{
    return (uint32_t)p[0] | (uint32_t)p[1] << 8 | (uint32_t)p[2] << 16 | (uint32_t)p[3] << 24;
}

/* The golden table with input ABBE_STUCK_INPUT's stuck check on, CRC fixed;
 * its size, or 0 if cap is too small. dst should be 4-byte aligned. */
static inline size_t abbe_stuck_blob(uint8_t *dst, size_t cap)
{
    size_t size = abbe_golden_thermal_blob_size;
    if (cap < size) {
        return 0u;
    }
    memcpy(dst, abbe_golden_thermal_blob, size);
    uint8_t *in = dst + abbe_stuck_get_u32(dst + 60) + 16u + 20u * ABBE_STUCK_INPUT;
    in[1] = (uint8_t)ABBE_STUCK_MIN;
    in[2] = (uint8_t)(ABBE_STUCK_RES_MILLI & 0xFFu);
    in[3] = (uint8_t)(ABBE_STUCK_RES_MILLI >> 8);
    uint32_t total = abbe_stuck_get_u32(dst + 8);
    uint32_t crc = abbe_crc32(0, dst, total - 4u);
    for (unsigned b = 0; b < 4u; b++) {
        dst[total - 4u + b] = (uint8_t)(crc >> (8u * b));
    }
    return size;
}

/* The stuck input's reading at sample i, m degC: base + a ramp while moving
 * (i < hold_from, i >= hold_to), held at the ramp's value of sample
 * hold_from - 1 in between (so the last change is at sample hold_from - 1). */
static inline int32_t abbe_stuck_reading_milli(int32_t base_milli, uint32_t i, uint32_t hold_from, uint32_t hold_to)
{
    uint32_t moving = i < hold_from ? i : i < hold_to ? hold_from - 1u : i - (hold_to - hold_from);
    return base_milli + ABBE_STUCK_RAMP_MILLI * (int32_t)moving;
}

#endif /* ABBE_THERMAL_STUCK_H */

/* abbe: CRC-32 (zlib / IEEE 802.3, reflected 0xEDB88320), bitwise.
 * A table lookup would be faster but costs 1 KiB of flash; tables are checked
 * once at load, so the 8 shifts per byte are the better trade. */
#include "abbe/model.h"

uint32_t abbe_crc32(uint32_t crc, const void *data, size_t size)
{
    const uint8_t *p = (const uint8_t *)data;
    crc = ~crc;
    for (size_t i = 0; i < size; i++) {
        crc ^= p[i];
        for (unsigned bit = 0; bit < 8u; bit++) {
            crc = (crc >> 1) ^ (0xEDB88320u & (0u - (crc & 1u)));
        }
    }
    return ~crc;
}

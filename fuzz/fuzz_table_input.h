/* The table harnesses' input: each input as it is and, when its total_size is
 * plausible, a copy with the CRC fixed up. Random bytes almost never carry a
 * valid CRC, which would stop every input at the CRC check; the copy lets
 * mutations reach the checks and the evaluation behind it. The copy has
 * exactly `size` bytes, so ASan still sees any read past the end. */
#ifndef ABBE_FUZZ_TABLE_INPUT_H
#define ABBE_FUZZ_TABLE_INPUT_H

#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "abbe/abbe.h"

static inline void fz_table_input(const uint8_t *data, size_t size, void (*exercise)(const uint8_t *, size_t))
{
    exercise(data, size);
    if (size < 64u) {
        return;
    }
    uint32_t total = (uint32_t)data[8] | ((uint32_t)data[9] << 8) | ((uint32_t)data[10] << 16) |
                     ((uint32_t)data[11] << 24);
    if (total >= 260u && total <= size && (total & 3u) == 0u) {
        uint8_t *copy = malloc(size);
        if (copy == NULL) {
            fprintf(stderr, "fuzz: out of memory\n");
            abort();
        }
        memcpy(copy, data, size);
        uint32_t crc = abbe_crc32(0u, copy, total - 4u);
        for (unsigned k = 0; k < 4u; k++) {
            copy[total - 4u + k] = (uint8_t)(crc >> (8u * k));
        }
        exercise(copy, size);
        free(copy);
    }
}

#endif

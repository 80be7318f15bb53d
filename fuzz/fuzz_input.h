/* A fuzzer's input read as a stream of little fields: every read succeeds,
 * past the end it gives zeros, so every input is a valid session. */
#ifndef ABBE_FUZZ_INPUT_H
#define ABBE_FUZZ_INPUT_H

#include <stddef.h>
#include <stdint.h>
#include <string.h>

typedef struct {
    const uint8_t *p;
    size_t n;
} fz_reader_t;

static inline uint8_t fz_u8(fz_reader_t *in)
{
    if (in->n == 0u) {
        return 0;
    }
    in->n--;
    return *in->p++;
}

static inline uint16_t fz_u16(fz_reader_t *in)
{
    uint16_t lo = fz_u8(in);
    return (uint16_t)(lo | (uint16_t)(fz_u8(in) << 8));
}

static inline uint32_t fz_u32(fz_reader_t *in)
{
    uint32_t lo = fz_u16(in);
    return lo | ((uint32_t)fz_u16(in) << 16);
}

/* n bytes into dst; zeros once the input is used up. */
static inline void fz_bytes(fz_reader_t *in, uint8_t *dst, size_t n)
{
    size_t k = n < in->n ? n : in->n;
    memcpy(dst, in->p, k);
    memset(dst + k, 0, n - k);
    in->p += k;
    in->n -= k;
}

#endif /* ABBE_FUZZ_INPUT_H */

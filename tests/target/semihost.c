/* Arm semihosting over `bkpt 0xAB` (Thumb), see the Arm "Semihosting for
 * AArch32 and AArch64" specification. */
#include "semihost.h"

#define SYS_WRITE0 0x04u
#define SYS_EXIT 0x18u
#define SYS_EXIT_EXTENDED 0x20u
#define ADP_STOPPED_APPLICATION_EXIT 0x20026u
#define ADP_STOPPED_RUN_TIME_ERROR 0x20023u

static uint32_t sh_call(uint32_t op, const void *arg)
{
    register uint32_t r0 __asm__("r0") = op;
    register const void *r1 __asm__("r1") = arg;
    __asm__ volatile("bkpt 0xAB" : "+r"(r0) : "r"(r1) : "memory");
    return r0;
}

void sh_puts(const char *s)
{
    (void)sh_call(SYS_WRITE0, s);
}

void sh_put_u32(uint32_t v)
{
    char buf[11];
    unsigned i = sizeof buf - 1u;
    buf[i] = '\0';
    do {
        buf[--i] = (char)('0' + (v % 10u));
        v /= 10u;
    } while (v != 0u);
    sh_puts(&buf[i]);
}

void sh_put_i32(int32_t v)
{
    if (v < 0) {
        sh_puts("-");
        sh_put_u32(0u - (uint32_t)v);
    } else {
        sh_put_u32((uint32_t)v);
    }
}

void sh_put_i64(int64_t v)
{
    /* 64-bit division would pull in __aeabi_uldivmod: subtract powers of ten. */
    static const uint64_t pow10[] = {
        1000000000000000000ull, 100000000000000000ull, 10000000000000000ull,
        1000000000000000ull, 100000000000000ull, 10000000000000ull, 1000000000000ull,
        100000000000ull, 10000000000ull, 1000000000ull, 100000000ull, 10000000ull,
        1000000ull, 100000ull, 10000ull, 1000ull, 100ull, 10ull, 1ull};
    char buf[21];
    unsigned n = 0u;
    int started = 0;
    uint64_t u = (uint64_t)v;
    if (v < 0) {
        buf[n++] = '-';
        u = 0u - u;
    }
    for (unsigned i = 0u; i < sizeof pow10 / sizeof pow10[0]; i++) {
        char d = '0';
        while (u >= pow10[i]) {
            u -= pow10[i];
            d++;
        }
        if (d != '0' || started || pow10[i] == 1u) {
            buf[n++] = d;
            started = 1;
        }
    }
    buf[n] = '\0';
    sh_puts(buf);
}

void sh_put_hex32(uint32_t v)
{
    static const char digits[] = "0123456789abcdef";
    char buf[11];
    buf[0] = '0';
    buf[1] = 'x';
    for (unsigned i = 0u; i < 8u; i++) {
        buf[2u + i] = digits[(v >> (28u - 4u * i)) & 0xFu];
    }
    buf[10] = '\0';
    sh_puts(buf);
}

void sh_exit(int status)
{
    uint32_t block[2];
    block[0] = ADP_STOPPED_APPLICATION_EXIT;
    block[1] = (uint32_t)status;
    (void)sh_call(SYS_EXIT_EXTENDED, block);
    /* A host without SYS_EXIT_EXTENDED: plain SYS_EXIT, success or failure. */
    (void)sh_call(SYS_EXIT, (const void *)(status == 0 ? ADP_STOPPED_APPLICATION_EXIT
                                                       : ADP_STOPPED_RUN_TIME_ERROR));
    for (;;) {
    }
}

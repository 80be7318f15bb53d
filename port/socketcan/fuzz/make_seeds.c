/* Writes the seed sessions of fuzz_can_node (the input encoding of
 * fuzz_can_node.c): OUTDIR/<name>.bin. Usage: make_seeds OUTDIR */
#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <string.h>

#define MAX_SEED 65536

typedef struct {
    uint8_t b[MAX_SEED];
    size_t n;
} seed_t;

static seed_t s;

static void put(uint8_t v)
{
    if (s.n < MAX_SEED) {
        s.b[s.n++] = v;
    }
}

static void put32(uint32_t v)
{
    for (unsigned k = 0; k < 4; k++) {
        put((uint8_t)(v >> (8 * k)));
    }
}

/* The op byte of step `kind` (op % 10) with the modifier bits `flags` (0x40, 0x80). */
static void op(unsigned kind, unsigned flags)
{
    for (unsigned v = 0; v < 256; v++) {
        if (v % 10u == kind && (v & 0xC0u) == flags) {
            put((uint8_t)v);
            return;
        }
    }
}

/* 8 data bytes: an INT32 at byte `at`, the rest zero (little-endian). */
static void data_i32(unsigned at, int32_t value)
{
    uint8_t d[8] = {0};
    uint32_t u = (uint32_t)value;
    for (unsigned k = 0; k < 4; k++) {
        d[at + k] = (uint8_t)(u >> (8 * k));
    }
    for (unsigned k = 0; k < 8; k++) {
        put(d[k]);
    }
}

static void tpdo(unsigned axis, int32_t incr, unsigned position_byte)
{
    op(0, 0);
    put((uint8_t)axis);
    data_i32(position_byte, incr);
}

static void sync(void)
{
    op(2, 0);
    data_i32(0, 0);
}

static void command(uint8_t code)
{
    op(3, 0);
    data_i32(0, code);
}

static void temperature(int16_t x, int16_t y, int16_t z)
{
    /* raw values (flag 0x40): the harness takes them as they are */
    op(4, 0x40);
    const int16_t v[3] = {x, y, z};
    for (unsigned j = 0; j < 3; j++) {
        put((uint8_t)((uint16_t)v[j] & 0xFFu));
        put((uint8_t)((uint16_t)v[j] >> 8));
    }
    put(0);
    put(0);
}

static void cycles(int from, int to, unsigned config_v, unsigned temp_every)
{
    for (int k = from; k < to; k++) {
        double a = 2.0 * 3.14159265358979 * k / 100.0;
        int32_t x = (int32_t)lround((250.0 + 100.0 * cos(a)) * 10000.0);
        int32_t y = (int32_t)lround(-(-200.0 + 100.0 * sin(a) + 100.0) * 2000.0);
        int32_t z = (int32_t)lround((-150.0 + 20.0 * sin(2.0 * a)) * 26214.4);
        tpdo(0, x, 0);
        if (k % 37 != 5) { /* Y drops out now and then */
            tpdo(1, y, 0);
        }
        tpdo(2, z, (config_v & 2u) ? 2u : 0u);
        if (temp_every != 0u && k % (int)temp_every == 0) {
            temperature((int16_t)(2000 + k), (int16_t)(1900 - k), (k & 1) ? (int16_t)-32768 : (int16_t)2300);
        }
        sync();
    }
}

static int write_seed(const char *dir, const char *name)
{
    char path[4096];
    snprintf(path, sizeof path, "%s/%s.bin", dir, name);
    FILE *f = fopen(path, "wb");
    if (f == NULL || fwrite(s.b, 1, s.n, f) != s.n || fclose(f) != 0) {
        fprintf(stderr, "make_seeds: cannot write %s\n", path);
        return 1;
    }
    s.n = 0;
    return 0;
}

int main(int argc, char **argv)
{
    if (argc != 2) {
        fprintf(stderr, "usage: %s OUTDIR\n", argv[0]);
        return 2;
    }
    const char *dir = argv[1];
    int bad = 0;

    /* a machine session: circle, temperature frames, stale Y, commands */
    put(0x01); /* temperature frame on */
    put(0x15);
    put(1); /* a model at start */
    cycles(0, 60, 0x01, 10);
    command(2);
    cycles(60, 80, 0x01, 10);
    command(1);
    cycles(80, 120, 0x01, 0);
    bad |= write_seed(dir, "circle-temperature");

    /* statusword layout, shared RPDO, info every 3 cycles, Y sign -1 */
    put(0x02 | 0x04 | 0x10 | 0x80);
    put(0x40);
    put(1);
    cycles(0, 40, 0x02, 0);
    bad |= write_seed(dir, "layouts");

    /* bad frames of every kind between cycles */
    put(0x01);
    put(0x00);
    put(1);
    cycles(0, 3, 0, 1);
    op(0, 0x80); put(0); put(3); data_i32(0, 1000);            /* TPDO, wrong DLC */
    op(2, 0x80); put(2); data_i32(0, 0);                       /* SYNC DLC 2 */
    op(3, 0x80); put(2); data_i32(0, 1);                       /* command DLC 2 */
    op(3, 0x40); data_i32(0, 0x55);                            /* unknown command */
    op(4, 0x80); put(5); data_i32(0, 2000);                    /* temperature DLC 5 */
    temperature(2000, 15001, 2000);                            /* out of range */
    op(5, 0); put32(0x181u | 0x40000000u); put(4); data_i32(0, 7); /* RTR */
    op(5, 0); put32(0x181u | 0x80000000u); put(4); data_i32(0, 7); /* 29-bit */
    op(5, 0); put32(0x20000004u); put(8); data_i32(0, 0x0400);  /* error frame */
    op(5, 0x80); put32(0x555u); put(9); data_i32(0, 0);         /* unknown id, length 9 */
    op(7, 0); put(5);                                          /* malformed record counted */
    cycles(3, 10, 0, 1);
    bad |= write_seed(dir, "bad-frames");

    /* model loads: good, queued twice (busy), damaged, truncated, through the buffer */
    put(0x00);
    put(0x07);
    put(0);
    cycles(0, 2, 0, 0);
    op(6, 0); put(0); put(0);                                  /* golden 0 as it is */
    op(6, 0); put(1); put(0);                                  /* busy: one is queued */
    cycles(2, 4, 0, 0);
    op(6, 0); put(1); put(0x01 | 0x08); put(0x10); put(0x01); put(0x40); /* a byte changed, CRC fixed */
    op(6, 0); put(2); put(0x01); put(0x20); put(0x00); put(0x01);      /* a byte changed: CRC refuses */
    op(6, 0); put(3); put(0x04); put(17);                              /* truncated */
    op(6, 0); put(0); put(0x10);                                       /* via the spare buffer */
    cycles(4, 6, 0, 0);
    op(6, 0); put(1); put(0x10 | 0x20); put(0xFF); put(0x7F);          /* buffer, wrong size */
    op(7, 0); put(3);                                                  /* reload request */
    op(7, 0); put(4);                                                  /* I/O failure noted */
    cycles(6, 10, 0, 0);
    bad |= write_seed(dir, "model-loads");

    /* frames through the stub driver and abbe_can_node_poll, with a RELOAD inside */
    put(0x00);
    put(0x00);
    put(1);
    op(8, 0); put(6);
    put(2); data_i32(0, 100000);
    put(6); data_i32(0, -5000);
    put(10); data_i32(0, 70000);
    put(1); data_i32(0, 0);
    put(0); data_i32(0, 4);                                    /* RELOAD: the poll stops after it */
    put(1); data_i32(0, 0);
    bad |= write_seed(dir, "poll");

    /* candump -l lines */
    static const char *const lines[] = {
        "(1700000000.123456) can0 181#A0860100\n",
        "(1700000000.000001) vcan0 12345678#DEADBEEF T\n",
        "(1.5) can1 123#R\n",
        "(1700000000.123456) can0 7FF#R8 R\n",
        "(1700000000.123456) can0 20000080#0000000000000000\n",
        "(1700000000.123456) can0 123##1DEADBEEF\n",
        "(1700000000.123456) can0 080#\n",
        "(1700000000.123456) can0 201#11.22.33.44_9\n",
    };
    put(0);
    put(0);
    put(0);
    for (size_t i = 0; i < sizeof lines / sizeof lines[0]; i++) {
        op(9, 0);
        size_t len = strlen(lines[i]);
        put((uint8_t)len);
        for (size_t k = 0; k < len; k++) {
            put((uint8_t)lines[i][k]);
        }
    }
    bad |= write_seed(dir, "log-lines");

    if (!bad) {
        printf("make_seeds: fuzz_can_node seeds in %s\n", dir);
    }
    return bad;
}

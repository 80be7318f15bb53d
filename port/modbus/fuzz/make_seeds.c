/* Writes the seed sessions of fuzz_modbus_regs (the input encoding of
 * fuzz_modbus_regs.c): OUTDIR/<name>.bin. Usage: make_seeds OUTDIR */
#include <stdint.h>
#include <stdio.h>

#define MAX_SEED 65536

static uint8_t buf[MAX_SEED];
static size_t len;

static void put(uint8_t v)
{
    if (len < MAX_SEED) {
        buf[len++] = v;
    }
}

static void put16(uint16_t v)
{
    put((uint8_t)(v & 0xFFu));
    put((uint8_t)(v >> 8));
}

static void put32(uint32_t v)
{
    put16((uint16_t)(v & 0xFFFFu));
    put16((uint16_t)(v >> 16));
}

enum { OP_READ = 0, OP_WRITE = 1, OP_CYCLE = 2, OP_CONTROL = 4, OP_UPLOAD = 5, OP_MISC = 6 };
enum { M_CMD = 0, M_COMMIT = 1, M_CHUNK = 2, M_TICK = 3, M_DISCONNECT = 4, M_COUNT = 5, M_TRIGGER = 6 };

/* conn 1..3 is 1 + byte % 3 */
static void conn(unsigned c)
{
    put((uint8_t)(c - 1u));
}

/* address: block b (0 ID, 1 ST, 2 UP, 3 IN, 4 OUT, 5 CT, 6 STAGING) + off */
static void addr(unsigned block, int off)
{
    put((uint8_t)block);
    put((uint8_t)(off + 2));
}

static void count(unsigned n)
{
    put((uint8_t)(n - 1u)); /* n - 1 + 1, bit 0x40 clear */
}

static void read_regs(unsigned c, unsigned block, int off, unsigned n)
{
    put(OP_READ);
    conn(c);
    addr(block, off);
    count(n);
}

static void upload(unsigned c, unsigned table, uint8_t how, uint8_t step_regs)
{
    put(OP_UPLOAD);
    conn(c);
    put((uint8_t)table);
    put(how);
    if (how & 1u) {
        put16(0x0123);
        put(0x10);
    }
    put((uint8_t)(step_regs - 1u));
    if (how & 4u) {
        put(40);
    }
    if (how & 16u) {
        put16(0x0200);
    }
    if (how & 32u) {
        put32(0xDEADBEEFu);
    }
}

static void cycle(unsigned c, int32_t x, int32_t y, int32_t z, uint16_t temp, uint16_t k)
{
    put(OP_CYCLE);
    put(0); /* how: valid values */
    const int32_t p[3] = {x, y, z};
    for (unsigned j = 0; j < 3; j++) {
        put32((uint32_t)p[j]);
        put((uint8_t)(k % 3u));
        put16(temp);
    }
    put(0);
    put16(k);
    conn(c);
}

static void control_limits(unsigned c, uint8_t fade, uint8_t stale)
{
    put(OP_CONTROL);
    put(1); /* the limit set */
    put(0);
    put(0);
    put(0);
    put(fade);
    put(stale);
    for (unsigned j = 0; j < 3; j++) {
        put(50);
        put(100);
        put16(5000);
        put(1);
    }
    conn(c);
}

static void misc(uint8_t what, unsigned c)
{
    put(OP_MISC);
    put(what);
    conn(c);
}

static int write_seed(const char *dir, const char *name)
{
    char path[4096];
    snprintf(path, sizeof path, "%s/%s.bin", dir, name);
    FILE *f = fopen(path, "wb");
    if (f == NULL || fwrite(buf, 1, len, f) != len || fclose(f) != 0) {
        fprintf(stderr, "make_seeds: cannot write %s\n", path);
        return 1;
    }
    len = 0;
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

    /* limits, upload, enable, a stream of cycles, the table swaps in */
    put(0x00);
    put(0x10);
    control_limits(1, 2, 3);
    upload(1, 1, 0, 123);
    misc(M_CMD, 1); put(0);            /* UP_CMD 0: not a command */
    put(OP_CONTROL); put(2); put(1); put(0); put(0); put(0); put(0);
    for (unsigned j = 0; j < 3; j++) { put(0); put(0); put16(0); put(0); }
    put(0); conn(1);                   /* CT_ENABLE = 1 */
    for (uint16_t k = 0; k < 60; k++) {
        cycle(1, 500000000 + 20000 * k, -700000000 + 5000 * k, -300000000, (uint16_t)(2000 + k), k);
    }
    read_regs(2, 0, 0, 20);
    read_regs(2, 1, 0, 27);
    read_regs(2, 4, 0, 15);
    bad |= write_seed(dir, "stream");

    /* two clients: busy, abort, damaged and refused uploads, disconnect, timeout */
    put(0x00 | 0x40);
    put(0x08 | 0x02); /* a model at start, upload timeout 3 s */
    upload(1, 0, 0x01 | 0x02, 60);      /* a byte changed, CRC fixed: the table's checks */
    upload(2, 2, 0x01, 100);            /* a byte changed: CRC_MISMATCH */
    upload(1, 3, 0x04, 50);             /* short: INCOMPLETE */
    upload(3, 0, 0x10, 123);            /* commit length 512 */
    upload(1, 0, 0x20, 123);            /* wrong CRC */
    misc(M_CMD, 1); put(1);             /* BEGIN by 1 */
    misc(M_CMD, 2); put(1);             /* busy */
    misc(M_CHUNK, 1); put16(0); put(10);
    for (unsigned k = 0; k < 16; k++) put((uint8_t)k);
    read_regs(1, 6, 0, 10);             /* staging read by the owner */
    read_regs(2, 6, 0, 10);             /* busy */
    misc(M_DISCONNECT, 1);
    misc(M_CMD, 2); put(1);
    misc(M_TICK, 2); put16(4000);       /* timeout */
    misc(M_CMD, 3); put(2);             /* ABORT without a session */
    misc(M_COMMIT, 3); put16(100); put32(0);
    bad |= write_seed(dir, "sessions");

    /* word order low, raw requests across the blocks */
    put(0x01 | 0x02);
    put(0x00);
    upload(1, 0, 0x08, 30);             /* a retried chunk */
    read_regs(1, 0, 8, 2);
    read_regs(1, 0, 19, 2);             /* across the block end */
    read_regs(1, 3, -1, 2);             /* unmapped */
    put(OP_WRITE); conn(1); addr(3, 1); count(2); put16(1); put16(2);         /* half an int32 */
    put(OP_WRITE); conn(1); addr(5, 2); count(1); put16(0);                   /* CT_WORD_ORDER 0 */
    put(OP_WRITE); conn(1); addr(3, 9); count(3); put16(0x8000); put16(0x7FFF); put16(2100);
    put(OP_WRITE); conn(2); addr(0, 0); count(1); put16(7);                   /* read-only */
    put(OP_WRITE); conn(2); addr(2, 0); count(2); put16(1); put16(2);         /* UP_CMD as 2 regs */
    put(OP_WRITE); conn(2); addr(6, 0); count(4); put32(0x45424241u); put32(0);  /* no session */
    cycle(1, 100, 200, 300, 0x8000, 5);
    misc(M_COUNT, 1); put(0x10); put(2); put(3); put16(7);
    misc(M_TRIGGER, 1); put16(42);
    bad |= write_seed(dir, "raw-requests");

    if (!bad) {
        printf("make_seeds: fuzz_modbus_regs seeds in %s\n", dir);
    }
    return bad;
}

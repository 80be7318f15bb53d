/* Eva harnesses of the Modbus port's register map (port/modbus/src/regs*.c),
 * one per entry point (docs/proofs.md, "Modbus"), each after any sequence of
 * earlier requests (a loop Eva analyses for every number of iterations),
 * from any of two connections, starting without a table, with an event hook:
 *   PROOF_ENTRY_WRITE   abbe_mb_regs_write (FC06 / FC16): any address, any
 *                       count 0 .. 124 (one past the Modbus limit), unknown
 *                       bytes; with ticks of any clock value and disconnects;
 *   PROOF_ENTRY_UPLOAD  the upload session: begin, chunks of 1 .. 123
 *                       registers of unknown bytes at any staging address
 *                       (tables of every length up to ABBE_MB_STAGING_MAX,
 *                       16384 B), commit of any length and CRC, abort, ticks,
 *                       disconnects, the other connection's requests;
 *   PROOF_ENTRY_READ    abbe_mb_regs_read (FC03 / FC04): any address, any
 *                       count 0 .. 126, after any writes.
 * The library calls that read a table's content are modelled by
 * tests/proofs/modbus_lib.c (any result in their documented ranges). */
#include "__fc_builtin.h"

#include "abbe/modbus_port.h"

#define PROOF_WRITE_MAX 124u /* ABBE_MB_MAX_WRITE + 1: refused, and proven so */
#define PROOF_READ_MAX 126u

static abbe_mb_regs_t regs;
static uint8_t values_be[2u * PROOF_WRITE_MAX];
static uint16_t dst[PROOF_READ_MAX];
static unsigned events_seen;

static void on_event(void *ctx, const abbe_mb_event_t *ev)
{
    //@ assert event_read: \valid_read(ev) && \initialized(ev);
    (void)ctx;
    events_seen = ev->kind;
}

static uint32_t any_conn(void)
{
    return Frama_C_unsigned_int_interval(1u, 2u);
}

/* one write request of unknown bytes */
static void any_write(uint16_t addr_min, uint16_t addr_max, uint16_t count_min, uint16_t count_max)
{
    Frama_C_make_unknown((char *)values_be, sizeof values_be);
    const uint16_t addr = (uint16_t)Frama_C_unsigned_int_interval(addr_min, addr_max);
    const uint16_t count = (uint16_t)Frama_C_unsigned_int_interval(count_min, count_max);
    (void)abbe_mb_regs_write(&regs, any_conn(), addr, count, values_be);
}

int main(void)
{
    abbe_mb_regs_config_t cfg;
    abbe_mb_regs_default_config(&cfg);
    if (abbe_mb_regs_init(&regs, &cfg, NULL, 0u) != ABBE_OK) {
        return 1;
    }
    abbe_mb_regs_set_event_hook(&regs, on_event, NULL);
    /* the bank indices stay banks or -1 (checked by Eva at every iteration;
     * without it the widening takes them to the int8_t range) */
    /*@ loop invariant banks: -1 <= regs.running < ABBE_MB_BANKS && -1 <= regs.pending < ABBE_MB_BANKS &&
                              -1 <= regs.staging < ABBE_MB_BANKS && -1 <= regs.th_bank < ABBE_MB_BANKS; */
    while (Frama_C_nondet(0, 1)) {
        switch (Frama_C_interval(0, 2)) {
        case 0:
#if defined(PROOF_ENTRY_UPLOAD)
            switch (Frama_C_interval(0, 2)) {
            case 0: /* UP_CMD: begin, abort or any other value */
                any_write(ABBE_MB_REG_UP_CMD, ABBE_MB_REG_UP_CMD, 1u, 1u);
                break;
            case 1: /* a chunk anywhere in the staging registers */
                any_write(ABBE_MB_REG_STAGING, 0xFFFFu, 1u, 123u);
                break;
            default: /* commit: any length, any CRC */
                any_write(ABBE_MB_REG_UP_COMMIT, ABBE_MB_REG_UP_COMMIT, 4u, 4u);
                break;
            }
#else
            any_write(0u, 0xFFFFu, 0u, PROOF_WRITE_MAX);
#endif
            break;
        case 1:
            abbe_mb_regs_tick(&regs, Frama_C_unsigned_int_interval(0u, 0xFFFFFFFFu));
            break;
        default:
            abbe_mb_regs_disconnect(&regs, any_conn());
            break;
        }
    }
#if defined(PROOF_ENTRY_READ)
    {
        const uint16_t addr = (uint16_t)Frama_C_unsigned_int_interval(0u, 0xFFFFu);
        const uint16_t count = (uint16_t)Frama_C_unsigned_int_interval(0u, PROOF_READ_MAX);
        (void)abbe_mb_regs_read(&regs, any_conn(), addr, count, dst);
    }
#endif
    return (int)(events_seen & 1u);
}

/* Eva harness: the Modbus port's register map (port/modbus/src/regs.c), the
 * code every request reaches: any sequence of register writes (FC6/FC16: any
 * address, count 0..PROOF_REGS, unknown bytes), reads (any address and
 * count), ticks of any clock value and disconnects, from any of two
 * connections, starting without a table (docs/proofs.md). The writes include
 * the upload session (open, chunks, commit) and the inputs that run a
 * compensation cycle. */
#include "__fc_builtin.h"

#include "abbe/modbus_port.h"

#ifndef PROOF_REGS
#define PROOF_REGS 8
#endif

static abbe_mb_regs_t regs;
static uint8_t values_be[2 * PROOF_REGS];
static uint16_t dst[125];

int main(void)
{
    abbe_mb_regs_config_t cfg;
    abbe_mb_regs_default_config(&cfg);
    if (abbe_mb_regs_init(&regs, &cfg, NULL, 0u) != ABBE_OK) {
        return 1;
    }
    while (Frama_C_nondet(0, 1)) {
        const uint32_t conn = Frama_C_unsigned_int_interval(1u, 2u);
        const uint16_t addr = (uint16_t)Frama_C_unsigned_int_interval(0u, 65535u);
        switch (Frama_C_interval(0, 3)) {
        case 0: {
            Frama_C_make_unknown((char *)values_be, sizeof values_be);
            const uint16_t count = (uint16_t)Frama_C_unsigned_int_interval(0u, PROOF_REGS);
            (void)abbe_mb_regs_write(&regs, conn, addr, count, values_be);
            break;
        }
        case 1:
            (void)abbe_mb_regs_read(&regs, conn, addr, (uint16_t)Frama_C_unsigned_int_interval(0u, 125u), dst);
            break;
        case 2:
            abbe_mb_regs_tick(&regs, Frama_C_unsigned_int_interval(0u, 0xFFFFFFFFu));
            break;
        default:
            abbe_mb_regs_disconnect(&regs, conn);
            break;
        }
    }
    return 0;
}

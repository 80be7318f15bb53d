/* Eva harness: the LinuxCNC port's table-file reader (port/linuxcnc,
 * abbe_lcnc_read_file) into a buffer of every capacity up to PROOF_MAX_SIZE,
 * with whatever the file system returns (Frama-C's libc contracts of fopen,
 * fread, ferror; docs/proofs.md). */
#include "__fc_builtin.h"
#include <stdint.h>

#include "abbe_lcnc_file.h"

#ifndef PROOF_MAX_SIZE
#define PROOF_MAX_SIZE 256
#endif

static uint32_t backing[PROOF_MAX_SIZE / 4u];
static char why[128];

int main(void)
{
    size_t capacity = Frama_C_interval(0, PROOF_MAX_SIZE);
    size_t why_size = Frama_C_interval(1, (int)sizeof why);
    size_t size = 0;
    int rc = abbe_lcnc_read_file("table.bin", backing, capacity, &size, why, why_size);
    return rc;
}

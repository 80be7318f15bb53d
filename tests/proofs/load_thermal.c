/* Eva harness (format 1.0-1.3 tables): abbe_thermal_load on every table of unknown bytes of every
 * length 0..PROOF_MAX_SIZE (docs/proofs.md). */
#include "__fc_builtin.h"
#include "abbe/thermal.h"

#ifndef PROOF_MAX_SIZE
#define PROOF_MAX_SIZE 512
#endif

static uint32_t backing[PROOF_MAX_SIZE / 4u];

int main(void)
{
    uint8_t *arr = (uint8_t *)backing;
    Frama_C_make_unknown((char *)arr, PROOF_MAX_SIZE);
    size_t size = Frama_C_interval(0, PROOF_MAX_SIZE);
    //@ split size;
    /* the table ends where the buffer does: a read past size is a read past the array */
    const uint8_t *blob = arr + (PROOF_MAX_SIZE - size);
    abbe_model_t model;
    abbe_thermal_model_t thermal;
    abbe_status_t st = abbe_thermal_load(&model, &thermal, blob, size);
    //@ merge size;
    return (int)st;
}

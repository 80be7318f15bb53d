/* The hypothesis 'sincos_range' of the Eva proofs (lib/src/basis_q.h):
 * abbe_sincos_q30_pair gives |sin|, |cos| <= 2^30 (Q30) for every phase.
 * Checked on all 2^32 phases (about 25 s of one core); scripts/prove.sh
 * compiles and runs it next to the Eva harnesses, whose 'sincos_range'
 * assertions may stay unknown to Eva only if this passes. Exit 1 naming the
 * first phase out of range. */
#include <inttypes.h>
#include <stdio.h>

#include "internal.h"

int main(void)
{
    uint32_t phase = 0u;
    int32_t lo = 0, hi = 0;
    do {
        const uint64_t pair = abbe_sincos_q30_pair(phase);
        const int32_t s = abbe_u32_to_i32((uint32_t)pair);
        const int32_t c = abbe_u32_to_i32((uint32_t)(pair >> 32));
        if (s < -ABBE_Q30_ONE || s > ABBE_Q30_ONE || c < -ABBE_Q30_ONE || c > ABBE_Q30_ONE) {
            printf("sincos_range: phase 0x%08" PRIx32 ": sin %" PRId32 ", cos %" PRId32 " beyond +/-2^30\n", phase, s,
                   c);
            return 1;
        }
        lo = s < lo ? s : lo;
        lo = c < lo ? c : lo;
        hi = s > hi ? s : hi;
        hi = c > hi ? c : hi;
        phase++;
    } while (phase != 0u);
    printf("sincos_range: all 2^32 phases, sin and cos in [%" PRId32 ", %" PRId32 "]\n", lo, hi);
    return 0;
}

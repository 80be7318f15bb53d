/* Eva harness: abbe_sincos_q30_pair (sincos_q.c) at every phase, 0..2^32-1:
 * no runtime error in its body. Its range (|sin|, |cos| <= 2^30, the
 * hypothesis 'sincos_range' of basis_q.h) is checked on every phase by
 * hypotheses.c, which this proof makes sound to run compiled: a body free of
 * undefined behaviour computes the same bits on the host as in C's semantics. */
#include "__fc_builtin.h"
#include "internal.h"

int main(void)
{
    const uint32_t phase = Frama_C_unsigned_int_interval(0u, UINT32_MAX);
    (void)abbe_sincos_q30_pair(phase);
    return 0;
}

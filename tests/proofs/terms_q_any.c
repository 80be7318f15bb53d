/* Eva harness: the fixed-point term kernel abbe_axis_terms_q (terms_q.c: the
 * six-term kernel; terms_sparse_q.c: the sparse one) on any axis layout the
 * loader accepts and any scalars (tests/proofs/any_layout.h: every term mask,
 * trend degree, harmonic count and reversal row count, the array placed so
 * that a read past the largest array of the mask is a read past the buffer),
 * coefficients in the 40-row box, every offset d (all of uint32, a superset
 * of [0, span]). Proves the kernel free of runtime errors there and its
 * contract (terms_q_contract.h: the term ranges), which eval_q_any_layout.c
 * then uses in place of the kernel (docs/proofs.md). */
#include "terms_q_contract.h"
#include "any_layout.h"

static abbe_axis_model_t ax;
static int32_t coef[ANY_COEF_WORDS];

int main(void)
{
    any_axis(&ax, coef);
    int32_t value[ABBE_TERMS];
    abbe_axis_terms_q(&ax, Frama_C_unsigned_int_interval(0u, UINT32_MAX), value);
    return 0;
}

/* abbe: fitted term values of a sparse axis, fixed point (see terms_q.c).
 * Built -Os on the Cortex-M: the basis code once more, for the rare table with
 * fewer than six terms on an axis. */
#include "basis_q.h"

/* A sparse axis (n_terms < 6 packed columns, column col holding the col-th
 * present term): rare, so built for a small stack and little code rather
 * than for speed: one column at a time, each with its own pass of the basis
 * and a single accumulator. */
void abbe_axis_terms_sparse_q(const abbe_axis_model_t *ax, uint32_t d, int32_t value[ABBE_TERMS])
{
    const unsigned stride = 4u * ax->n_terms;
    for (unsigned t = 0; t < ABBE_TERMS; t++) {
        const unsigned col = ax->column[t];
        /* no basis rows: no coefficient array either (NULL), every term is 0 */
        if (col == 0xFFu || ax->n_basis == 0u) {
            value[t] = 0;
            continue;
        }
        const uint8_t *row = ax->coef_q + 4u * col;
        /* linear or angular: shifts 32 or 31, computed (a select here would
         * let the compiler duplicate the whole loop) */
        const unsigned shift = (unsigned)LIN_SHIFT - (unsigned)(t >= 3u);
        int64_t acc = (int64_t)1 << (shift - 1u);
#define FIRST1() do { MAC1(acc, 0); row += stride; } while (0)
#define ROW1(b) do { MAC(acc, 0, (b)); row += stride; } while (0)
        ABBE_BASIS_Q(ax, d, FIRST1, ROW1);
#undef FIRST1
#undef ROW1
        value[t] = (int32_t)(acc >> shift);
    }
}

#undef MAC
#undef MAC1
#undef LD

/* A LEAN REFERENCE evaluator, for the benchmark only: not part of the
 * library, and not a replacement for it.
 *
 * The same 18-term model as abbe (Chebyshev trend + Fourier blocks per term,
 * Eq. 3 with squareness) written the way a lean float implementation would
 * be: float positions, float Chebyshev argument, a float Fourier phase with
 * a float quarter-turn reduction, one polynomial sin/cos per block,
 * harmonics by recurrence, six accumulators per row. It leaves out what abbe
 * guarantees and pays for: the integer argument reduction (its phase loses
 * 2^-24 of the turns from the origin), clamping to the travel and the flag,
 * NaN/Inf checks, the tool offset, backlash and thermal terms. The benchmark
 * prints abbe's instruction counts against it and against the naive double
 * evaluator (naive_ref.c). Built the same way as the library (same flags). */
#ifndef ABBE_BENCH_LEAN_REF_H
#define ABBE_BENCH_LEAN_REF_H

#include <stddef.h>
#include <stdint.h>

typedef struct {
    const float *coef;      /* n_basis x n_terms, row-major, in the table's units */
    float scale[6];         /* per column: to um (linear) or urad (angular) */
    int term_of_col[6];
    int n_terms, trend_rows, harmonics[2];
    float min_mm, inv_half_span, mid_mm;
    float period_turns_per_mm[2], origin_mm[2];
} lean_axis_t;

typedef struct {
    float ref_mm[3];
    float s_xy, s_xz, s_yz; /* urad */
    lean_axis_t axis[3];
} lean_model_t;

/* Point into a blob the library has validated (4-byte aligned); 0 on success. */
int lean_load(lean_model_t *m, const uint8_t *blob, size_t size);

/* (dX, dY, dZ) in um at pos_mm. */
void lean_eval(const lean_model_t *m, const float pos_mm[3], float err_um[3]);

#endif

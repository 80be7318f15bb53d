/* A naive reference evaluation of the abbe model, for the benchmark only:
 * double precision, libm sin/cos for every harmonic of every term, each term
 * evaluated on its own, Eq. 3 written out as in docs/table-format.md.
 * It is what a straightforward port of the float64 Python reference looks
 * like, and the yardstick the library's instruction counts are compared with. */
#ifndef ABBE_BENCH_NAIVE_REF_H
#define ABBE_BENCH_NAIVE_REF_H

#include <stddef.h>
#include <stdint.h>

#define NAIVE_MAX_BASIS 40

typedef struct {
    double travel_min_mm, travel_max_mm;
    int trend_rows;                  /* trend degree + 1, or 0 */
    int harmonics[2];
    double period_mm[2], origin_mm[2];
    int present[6];                  /* term present */
    double coef[6][NAIVE_MAX_BASIS]; /* per term, per basis row: um or urad */
    double backlash_um;              /* reversal B, um */
    int reversal_rows;               /* format 1.1 reversal block (0 = none) */
    double reversal_um[8];           /* its Chebyshev coefficients, um */
    double expansion_per_k;          /* alpha, 1/K */
    double offset_um_per_k;          /* o, um/K */
    double tref_c;                   /* reference temperature, deg C */
} naive_axis_t;

typedef struct {
    unsigned features;
    double ref_mm[3], tool_mm[3];
    double s_xy_urad, s_xz_urad, s_yz_urad;
    naive_axis_t axis[3];
} naive_model_t;

/* Parse a blob (no validation beyond the magic and sizes: the bench only
 * feeds it tables the library has validated). Returns 0 on success. */
int naive_load(naive_model_t *m, const uint8_t *blob, size_t size);

/* Spatial error (dX, dY, dZ) in um at pos_mm, backlash direction state
 * dir[-1..1] and axis temperatures temp_c. */
void naive_eval(const naive_model_t *m, const double pos_mm[3], const double dir[3],
                const double temp_c[3], double err_um[3]);

#endif /* ABBE_BENCH_NAIVE_REF_H */

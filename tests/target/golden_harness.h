/* Golden-vector harness shared by the target tests: loops over the golden
 * tables, points and terms, keeps the worst errors, reports over semihosting.
 * Integer only, so the fixed-point image stays free of float code. Each
 * variant supplies how one point and one term are evaluated. */
#ifndef ABBE_TARGET_GOLDEN_HARNESS_H
#define ABBE_TARGET_GOLDEN_HARNESS_H

#include <stdint.h>

#include "abbe/abbe.h"
#include "golden_data.h"

typedef struct {
    const char *name; /* "f32" or "q": used in the report */
    /* Evaluate golden point p: error in pm per axis and the result flags. */
    abbe_status_t (*eval_point)(const abbe_model_t *m, const abbe_golden_point_t *p,
                                int64_t got_pm[ABBE_AXES], uint32_t *flags);
    /* Evaluate golden term g: value in pm (linear) or prad (angular). */
    abbe_status_t (*eval_term)(const abbe_model_t *m, const abbe_golden_term_t *g, int64_t *got_pico);
    /* The expectation of this variant (they differ: each at its own input). */
    int32_t (*expect_point)(const abbe_golden_point_t *p, unsigned axis);
    int32_t (*expect_term)(const abbe_golden_term_t *g);
} golden_variant_t;

/* Run every golden table; returns the exit status (0 only if all pass). */
int golden_run(const golden_variant_t *v);

#endif

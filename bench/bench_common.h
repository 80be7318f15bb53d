/* Shared set-up of the benchmark programs (host and target): the "paper"
 * golden table and the inputs. Header-only so each program stays one file. */
#ifndef ABBE_BENCH_COMMON_H
#define ABBE_BENCH_COMMON_H

#include <stdint.h>

#include "abbe/abbe.h"
#include "golden_data.h"

#define BENCH_TABLE "paper"

static inline int bench_streq(const char *a, const char *b)
{
    while (*a != '\0' && *a == *b) {
        a++;
        b++;
    }
    return *a == *b;
}

/* The tables measured besides BENCH_TABLE (format 1.1, issue 14): the paper
 * table with a constant backlash on every axis (format 1.0) and the same with
 * reversal blocks of degree 3, 7 and 0: their difference is the blocks' cost.
 * A library built without the blocks (ABBE_NO_REVERSAL) cannot load the
 * second one and skips it. */
#define BENCH_BACKLASH_TABLE "backlash"
#define BENCH_REVERSAL_TABLE "reversal"

static inline const abbe_golden_table_t *bench_table_named(const char *name)
{
    for (uint32_t i = 0; i < abbe_golden_table_count; i++) {
        if (bench_streq(abbe_golden_tables[i].name, name)) {
            return &abbe_golden_tables[i];
        }
    }
    return NULL;
}

static inline const abbe_golden_table_t *bench_table(void)
{
    return bench_table_named(BENCH_TABLE);
}

/* Compensator limits wide enough that a realistic table never trips them. */
static inline void bench_comp_config(abbe_comp_config_t *cfg)
{
    static const abbe_comp_config_t zero;
    *cfg = zero;
    for (unsigned j = 0; j < ABBE_AXES; j++) {
        cfg->warn_nm[j] = 500000;
        cfg->limit_nm[j] = 1000000;
        cfg->rate_nm_per_cycle[j] = 100000;
        cfg->axis_sign[j] = 1;
    }
    cfg->fade_cycles = 1;
    cfg->stale_cycles = 10;
}

/* Cycle k of a diagonal move at 200 mm/min sampled at 1 kHz (3333 nm per
 * cycle per axis) from (50, -50, -50) mm: inside the paper table's travel. */
static inline void bench_path_nm(uint32_t k, int32_t pos_nm[ABBE_AXES])
{
    static const int32_t start_nm[ABBE_AXES] = {50000000, -50000000, -50000000};
    static const int32_t step_nm[ABBE_AXES] = {3333, -3333, -3333};
    for (unsigned j = 0; j < ABBE_AXES; j++) {
        pos_nm[j] = start_nm[j] + (int32_t)(k % 60000u) * step_nm[j];
    }
}

#endif /* ABBE_BENCH_COMMON_H */

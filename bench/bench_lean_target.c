/* Target benchmark of the LEAN REFERENCE evaluator (bench/lean_ref.c: float,
 * one polynomial sin/cos per block, none of abbe's guarantees) on the
 * "paper" table, built like the library (same flags, no newlib). Same marks
 * and PLAN protocol as bench_target.c. */
#include <stdint.h>

#include "bench_common.h"
#include "lean_ref.h"
#include "semihost.h"

#define BENCH_POINTS 8u

static lean_model_t lmodel;
static volatile float sink;

__attribute__((noinline)) void bench_mark(void)
{
    __asm__ volatile("" ::: "memory");
}

int main(void)
{
    const abbe_golden_table_t *t = bench_table();
    if (t == NULL || lean_load(&lmodel, t->blob, t->blob_size) != 0) {
        sh_puts("bench_lean_target: cannot load the 'paper' table\n");
        return 2;
    }
    const abbe_golden_point_t *pts = &abbe_golden_points[t->first_point];
    sh_puts("PLAN calibration 1\n");
    bench_mark();
    bench_mark();
    sh_puts("PLAN lean 8\n");
    for (uint32_t i = 0; i < BENCH_POINTS; i++) {
        float pos[3] = {pts[i].pos_mm[0], pts[i].pos_mm[1], pts[i].pos_mm[2]}, err[3];
        bench_mark();
        lean_eval(&lmodel, pos, err);
        bench_mark();
        sink = err[0];
    }
    sh_puts("DONE\n");
    return 0;
}

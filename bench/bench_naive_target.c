/* Target benchmark of the naive reference (bench/naive_ref.c: double, newlib
 * libm sin/cos per harmonic) on the "paper" table: the yardstick for the
 * library's counts. Same marks and PLAN protocol as bench_target.c. This
 * image links newlib (libm, libc); the library's own images never do. */
#include <stdint.h>

#include "bench_common.h"
#include "naive_ref.h"
#include "semihost.h"

#define BENCH_POINTS 8u

static naive_model_t nmodel;
static volatile double sink;

__attribute__((noinline)) void bench_mark(void)
{
    __asm__ volatile("" ::: "memory");
}

/* newlib's libm may set errno through __errno(); nothing else is needed. */
int main(void)
{
    const abbe_golden_table_t *t = bench_table();
    if (t == NULL || naive_load(&nmodel, t->blob, t->blob_size) != 0) {
        sh_puts("bench_naive_target: cannot load the 'paper' table\n");
        return 2;
    }
    const abbe_golden_point_t *pts = &abbe_golden_points[t->first_point];
    sh_puts("PLAN calibration 1\n");
    bench_mark();
    bench_mark();
    sh_puts("PLAN naive 8\n");
    for (uint32_t i = 0; i < BENCH_POINTS; i++) {
        const abbe_golden_point_t *p = &pts[i];
        double pos[3], dir[3], temp[3], err[3];
        for (int j = 0; j < 3; j++) {
            pos[j] = p->pos_mm[j];
            dir[j] = p->dir_state[j];
            temp[j] = p->temp_c[j];
        }
        bench_mark();
        naive_eval(&nmodel, pos, dir, temp, err);
        bench_mark();
        sink = err[0];
    }
    sh_puts("DONE\n");
    return 0;
}

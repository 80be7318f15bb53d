/* Five-axis target benchmark: instructions per call under QEMU (the protocol
 * of bench_target.c: marks around each call, PLAN lines, STACK lines; read by
 * scripts/bench_five.py). Per five-axis golden table (tests/golden/
 * golden_five.*), BENCH_FIVE_POINTS points: abbe_five_error_eval_f32 / _q and
 * the compensator's five-axis cycle, and the stack each uses. */
#include <stdint.h>

#include "abbe/abbe.h"
#include "golden_five.h"
#include "semihost.h"

#define BENCH_FIVE_POINTS 8u

static abbe_five_model_t model;
static abbe_comp_t comp;
static volatile int32_t sink;
static const abbe_golden_five_point_t *points;
static const char *table_name = "";

__attribute__((noinline)) void bench_mark(void)
{
    __asm__ volatile("" ::: "memory");
}

static void plan(const char *what, uint32_t n)
{
    sh_puts("PLAN ");
    sh_puts(what);
    if (table_name[0] != '\0') {
        sh_puts("@");
        sh_puts(table_name);
    }
    sh_puts(" ");
    sh_put_u32(n);
    sh_puts("\n");
}

static uint32_t stack_used(void (*fn)(uint32_t), uint32_t arg)
{
    uint32_t *sp;
    __asm__ volatile("mov %0, sp" : "=r"(sp));
    volatile uint32_t *lo = sp - 512;
    for (volatile uint32_t *p = lo; p < sp; p++) {
        *p = 0xC5C5C5C5u;
    }
    fn(arg);
    volatile uint32_t *p = lo;
    while (p < sp && *p == 0xC5C5C5C5u) {
        p++;
    }
    return (uint32_t)((uintptr_t)sp - (uintptr_t)p);
}

static void report_stack(const char *what, void (*fn)(uint32_t))
{
    plan("stack", 1u);
    uint32_t used = stack_used(fn, 3u);
    sh_puts("STACK ");
    sh_puts(what);
    sh_puts("@");
    sh_puts(table_name);
    sh_puts(" ");
    sh_put_u32(used);
    sh_puts("\n");
}

#if defined(BENCH_F32)
static void run_f32(uint32_t i)
{
    const abbe_golden_five_point_t *p = &points[i];
    abbe_five_input_f32_t in = {{p->pos_mm[0], p->pos_mm[1], p->pos_mm[2]}, {p->angle_deg[0], p->angle_deg[1]},
                                {0.0f, 0.0f, 0.0f}, {20.0f, 20.0f, 20.0f}};
    abbe_five_error_f32_t out;
    bench_mark();
    abbe_five_error_eval_f32(&model, &in, &out);
    bench_mark();
    sink = (int32_t)out.flags;
}

static void run_comp_f32(uint32_t i)
{
    const abbe_golden_five_point_t *p = &points[i % BENCH_FIVE_POINTS];
    abbe_comp_input5_f32_t in = {{{p->pos_mm[0], p->pos_mm[1], p->pos_mm[2]}, {20.0f, 20.0f, 20.0f}, {1, -1, -1}, 1, 0},
                                 {p->angle_deg[0], p->angle_deg[1]}};
    abbe_comp_output5_t out;
    bench_mark();
    abbe_comp_step5_f32(&comp, &in, &out);
    bench_mark();
    sink = out.lin.corr_nm[0] + out.orient_nrad[0];
}
#endif

#if defined(BENCH_Q)
static void run_q(uint32_t i)
{
    const abbe_golden_five_point_t *p = &points[i];
    abbe_five_input_q_t in = {{p->pos_nm[0], p->pos_nm[1], p->pos_nm[2]}, {p->angle_udeg[0], p->angle_udeg[1]},
                              {0, 0, 0}, {20000, 20000, 20000}};
    abbe_five_error_q_t out;
    bench_mark();
    abbe_five_error_eval_q(&model, &in, &out);
    bench_mark();
    sink = (int32_t)out.flags;
}

static void run_comp_q(uint32_t i)
{
    const abbe_golden_five_point_t *p = &points[i % BENCH_FIVE_POINTS];
    abbe_comp_input5_q_t in = {{{p->pos_nm[0], p->pos_nm[1], p->pos_nm[2]}, {20000, 20000, 20000}, {1, -1, -1}, 1, 0},
                               {p->angle_udeg[0], p->angle_udeg[1]}};
    abbe_comp_output5_t out;
    bench_mark();
    abbe_comp_step5_q(&comp, &in, &out);
    bench_mark();
    sink = out.lin.corr_nm[0] + out.orient_nrad[0];
}
#endif

static void measure(const char *what, void (*fn)(uint32_t))
{
    plan(what, BENCH_FIVE_POINTS);
    for (uint32_t i = 0; i < BENCH_FIVE_POINTS; i++) {
        fn(i);
    }
}

static void comp_start(void)
{
    abbe_comp_config_t cfg = {{500000, 500000, 500000}, {1000000, 1000000, 1000000}, {1000, 1000, 1000}, 4, 4,
                              {1, 1, 1}};
    abbe_comp_init(&comp, &cfg, NULL);
    abbe_comp_swap_five_model(&comp, &model);
    abbe_comp_enable(&comp);
}

int main(void)
{
    plan("calibration", 1u);
    bench_mark();
    bench_mark();
    for (uint32_t t = 0; t < abbe_golden_five_table_count; t++) {
        const abbe_golden_five_table_t *g = &abbe_golden_five_tables[t];
        if (abbe_five_model_load(&model, g->blob, g->blob_size) != ABBE_OK) {
            sh_puts("bench_five_target: load failed\n");
            return 1;
        }
        table_name = g->name;
        points = &abbe_golden_five_points[g->first_point];
#if defined(BENCH_F32)
        measure("five_f32", run_f32);
        report_stack("five_f32", run_f32);
#endif
#if defined(BENCH_Q)
        measure("five_q", run_q);
        report_stack("five_q", run_q);
#endif
        comp_start();
#if defined(BENCH_F32)
        measure("comp5_f32", run_comp_f32);
        report_stack("comp5_f32", run_comp_f32);
#endif
#if defined(BENCH_Q)
        measure("comp5_q", run_comp_q);
        report_stack("comp5_q", run_comp_q);
#endif
    }
    sh_puts("DONE\n");
    return 0;
}

/* Target benchmark: exact instruction counts per call under QEMU.
 *
 * Every measured call sits between two calls of bench_mark(). Run with
 *   qemu-system-arm ... -singlestep -d exec,nochain -D exec.log
 * each executed instruction is one trace line; scripts/bench_report.py counts
 * the lines between marks (minus an empty pair, the calibration) in the order
 * announced by the "PLAN" lines this program prints. It also measures the
 * stack each call really uses (stack painted below SP, scanned after the call).
 *
 * The variants built in follow ABBE_WITH_F32 / ABBE_WITH_Q (BENCH_F32/BENCH_Q). */
#include <stdint.h>

#include "bench_common.h"
#include "semihost.h"

#define BENCH_POINTS 8u

static abbe_model_t model;
static abbe_comp_t comp;
static volatile int32_t sink;

__attribute__((noinline)) void bench_mark(void)
{
    __asm__ volatile("" ::: "memory");
}

/* The table of the measurements that follow: "" for BENCH_TABLE, else its
 * name, appended to each plan and stack label as "@name". */
static const char *table_suffix = "";

static void put_label(const char *what)
{
    sh_puts(what);
    if (table_suffix[0] != '\0') {
        sh_puts("@");
        sh_puts(table_suffix);
    }
}

static void plan(const char *what, uint32_t n)
{
    sh_puts("PLAN ");
    put_label(what);
    sh_puts(" ");
    sh_put_u32(n);
    sh_puts("\n");
}

/* Bytes of stack used by fn(): paint 2 KiB below SP, call, find the lowest
 * word changed. Includes fn's own frame (the wrappers below are tiny). */
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
    plan("stack", 1u); /* the call below passes its marks once more */
    uint32_t used = stack_used(fn, 3u);
    sh_puts("STACK ");
    put_label(what);
    sh_puts(" ");
    sh_put_u32(used);
    sh_puts("\n");
}

static const abbe_golden_point_t *points;

#if defined(BENCH_F32)
static void run_f32(uint32_t i)
{
    const abbe_golden_point_t *p = &points[i];
    abbe_input_f32_t in;
    abbe_error_f32_t out;
    for (unsigned j = 0; j < ABBE_AXES; j++) {
        in.pos_mm[j] = p->pos_mm[j];
        in.dir_state[j] = p->dir_state[j];
        in.temp_c[j] = p->temp_c[j];
    }
    bench_mark();
    abbe_error_eval_f32(&model, &in, &out);
    bench_mark();
    sink = (int32_t)out.flags;
}

static void run_comp_f32(uint32_t k)
{
    int32_t pos_nm[ABBE_AXES];
    abbe_comp_output_t out;
    bench_path_nm(k, pos_nm);
    abbe_comp_input_f32_t in = {{(float)pos_nm[0] * 1e-6f, (float)pos_nm[1] * 1e-6f,
                                 (float)pos_nm[2] * 1e-6f},
                                {20.0f, 20.0f, 20.0f}, {1, -1, -1}, 1, 0};
    bench_mark();
    abbe_comp_step_f32(&comp, &in, &out);
    bench_mark();
    sink = out.corr_nm[0] + (int32_t)out.flags;
}
#endif

#if defined(BENCH_Q)
static void run_q(uint32_t i)
{
    const abbe_golden_point_t *p = &points[i];
    abbe_input_q_t in;
    abbe_error_q_t out;
    for (unsigned j = 0; j < ABBE_AXES; j++) {
        in.pos_nm[j] = p->pos_nm[j];
        in.dir_state_q30[j] = p->dir_q30[j];
        in.temp_mdegc[j] = p->temp_mdegc[j];
    }
    bench_mark();
    abbe_error_eval_q(&model, &in, &out);
    bench_mark();
    sink = (int32_t)out.flags;
}

static void run_comp_q(uint32_t k)
{
    int32_t pos_nm[ABBE_AXES];
    abbe_comp_output_t out;
    bench_path_nm(k, pos_nm);
    abbe_comp_input_q_t in = {{pos_nm[0], pos_nm[1], pos_nm[2]},
                              {20000, 20000, 20000}, {1, -1, -1}, 1, 0};
    bench_mark();
    abbe_comp_step_q(&comp, &in, &out);
    bench_mark();
    sink = out.corr_nm[0] + (int32_t)out.flags;
}
#endif

static const abbe_golden_table_t *current;

static void run_load(uint32_t unused)
{
    const abbe_golden_table_t *t = current;
    (void)unused;
    bench_mark();
    abbe_status_t st = abbe_model_load(&model, t->blob, t->blob_size);
    bench_mark();
    sink = (int32_t)st;
}

static void comp_start(void)
{
    abbe_comp_config_t cfg;
    abbe_comp_output_t out;
    bench_comp_config(&cfg);
    abbe_comp_init(&comp, &cfg, &model);
    abbe_comp_enable(&comp);
    for (uint32_t k = 0; k < 4u; k++) { /* fade in */
        int32_t pos_nm[ABBE_AXES];
        bench_path_nm(k, pos_nm);
        abbe_comp_input_q_t in = {{pos_nm[0], pos_nm[1], pos_nm[2]},
                                  {20000, 20000, 20000}, {1, -1, -1}, 1, 0};
        abbe_comp_step_q(&comp, &in, &out);
    }
}

static void measure(const char *what, void (*fn)(uint32_t), uint32_t first)
{
    plan(what, BENCH_POINTS);
    for (uint32_t i = 0; i < BENCH_POINTS; i++) {
        fn(first + i);
    }
}

/* The evaluations and the compensator cycles on the current table, with the
 * compensator's stack (and the evaluations' too if eval_stack). */
static void measure_calls(int eval_stack)
{
#if defined(BENCH_F32)
    measure("f32", run_f32, 0u);
    if (eval_stack) {
        report_stack("f32", run_f32);
    }
#endif
#if defined(BENCH_Q)
    measure("q", run_q, 0u);
    if (eval_stack) {
        report_stack("q", run_q);
    }
#endif
    comp_start();
#if defined(BENCH_F32)
    measure("comp_f32", run_comp_f32, 4u);
    report_stack("comp_f32", run_comp_f32);
#endif
#if defined(BENCH_Q)
    measure("comp_q", run_comp_q, 4u + BENCH_POINTS);
    report_stack("comp_q", run_comp_q);
#endif
    (void)eval_stack;
}

/* Every call again on another table (plans labelled "@name"): the backlash and
 * reversal-block tables of bench_common.h. */
static void measure_table(const char *name)
{
    const abbe_golden_table_t *t = bench_table_named(name);
    if (t == NULL || abbe_model_load(&model, t->blob, t->blob_size) != ABBE_OK) {
        sh_puts("SKIP table ");
        sh_puts(name);
        sh_puts(" (not in the golden data, or refused by this library)\n");
        return;
    }
    table_suffix = name;
    current = t;
    points = &abbe_golden_points[t->first_point];
    measure_calls(0);
    table_suffix = "";
}

int main(void)
{
    const abbe_golden_table_t *t = bench_table();
    if (t == NULL) {
        sh_puts("bench_target: no 'paper' golden table\n");
        return 2;
    }
    current = t;
    points = &abbe_golden_points[t->first_point];

    /* Calibration: an empty pair of marks. */
    plan("calibration", 1u);
    bench_mark();
    bench_mark();

    plan("load", 1u);
    run_load(0u);
    if (sink != ABBE_OK) {
        sh_puts("bench_target: load failed\n");
        return 1;
    }
    report_stack("load", run_load);
    measure_calls(1);
    measure_table(BENCH_BACKLASH_TABLE);
    measure_table(BENCH_REVERSAL_TABLE);
    sh_puts("DONE\n");
    return 0;
}

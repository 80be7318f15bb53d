/* Thermal benchmark (format 1.3, abbe/thermal.h): exact instruction counts
 * under QEMU, as bench_target.c (marks around each call, PLAN lines; counted
 * by scripts/bench_thermal.py with scripts/bench_report.py's helpers).
 *
 * Per evaluation period: Eq. 3 alone (the paper table, as bench_target), and
 * Eq. 3 followed by abbe_thermal_apply_* (the thermal error added; steady:
 * nothing fades), apply alone steady and while fading; the compensator's
 * cycle with and without the thermal block. Per temperature sample:
 * abbe_thermal_update_* with the golden thermal model (16 temperatures + the
 * speed, 5 channels x 4 terms: the largest block), _q with a repeating dt
 * (cached weights) and with a new dt (20 64-bit divisions). */
#include <stdint.h>

#include "bench_common.h"
#include "golden_thermal.h"
#include "semihost.h"

#define N 8u

static abbe_model_t model, th_geo;
static abbe_thermal_model_t tm;
static abbe_thermal_state_t st;
static abbe_comp_t comp;
static volatile int32_t sink;
static const abbe_golden_point_t *points;
static const abbe_golden_thermal_sample_t *S = abbe_golden_thermal_samples;

__attribute__((noinline)) void bench_mark(void)
{
    __asm__ volatile("" ::: "memory");
}

static void plan(const char *what, uint32_t n)
{
    sh_puts("PLAN ");
    sh_puts(what);
    sh_puts(" ");
    sh_put_u32(n);
    sh_puts("\n");
}

#if defined(BENCH_F32)
static void warm_f32(uint32_t samples)
{
    abbe_thermal_init_f32(&st, &tm, 30.0f); /* one apply = a whole fade */
    for (uint32_t n = 0; n < samples; n++) {
        abbe_thermal_update_f32(&st, S[n].x, 0x1FFFFu, n ? S[n].dt_s : 0.0f);
        float e[3] = {0.0f, 0.0f, 0.0f};
        abbe_thermal_apply_f32(&st, e);
    }
}

static void eval_f32(uint32_t i, int with_thermal)
{
    const abbe_golden_point_t *p = &points[i];
    abbe_input_f32_t in;
    abbe_error_f32_t out;
    for (unsigned j = 0; j < ABBE_AXES; j++) {
        in.pos_mm[j] = p->pos_mm[j];
        in.dir_state[j] = p->dir_state[j];
        in.temp_c[j] = p->temp_c[j];
    }
    if (with_thermal) { /* a fresh sample, unmeasured: the watchdog stays quiet */
        abbe_thermal_update_f32(&st, S[40u + i].x, 0x1FFFFu, S[40u + i].dt_s);
    }
    bench_mark();
    abbe_error_eval_f32(&model, &in, &out);
    if (with_thermal) {
        abbe_thermal_apply_f32(&st, out.error_um);
    }
    bench_mark();
    sink = (int32_t)out.flags + (int32_t)out.error_um[0];
}
#endif

#if defined(BENCH_Q)
static void warm_q(uint32_t samples)
{
    abbe_thermal_init_q(&st, &tm, 30000000u);
    for (uint32_t n = 0; n < samples; n++) {
        abbe_thermal_update_q(&st, S[n].x_milli, 0x1FFFFu, n ? 15000u : 0u);
        int32_t e[3] = {0, 0, 0};
        abbe_thermal_apply_q(&st, e);
    }
}

static void eval_q(uint32_t i, int with_thermal)
{
    const abbe_golden_point_t *p = &points[i];
    abbe_input_q_t in;
    abbe_error_q_t out;
    for (unsigned j = 0; j < ABBE_AXES; j++) {
        in.pos_nm[j] = p->pos_nm[j];
        in.dir_state_q30[j] = p->dir_q30[j];
        in.temp_mdegc[j] = p->temp_mdegc[j];
    }
    if (with_thermal) {
        abbe_thermal_update_q(&st, S[40u + i].x_milli, 0x1FFFFu, 15000u);
    }
    bench_mark();
    abbe_error_eval_q(&model, &in, &out);
    if (with_thermal) {
        abbe_thermal_apply_q(&st, out.error_nm);
    }
    bench_mark();
    sink = (int32_t)out.flags + out.error_nm[0];
}
#endif

int main(void)
{
    const abbe_golden_table_t *t = bench_table();
    if (t == NULL || abbe_model_load(&model, t->blob, t->blob_size) != ABBE_OK ||
        abbe_thermal_load(&th_geo, &tm, abbe_golden_thermal_blob, abbe_golden_thermal_blob_size) != ABBE_OK) {
        sh_puts("bench_thermal_target: load failed\n");
        return 1;
    }
    points = &abbe_golden_points[t->first_point];
    plan("calibration", 1u);
    bench_mark();
    bench_mark();
    abbe_comp_config_t cfg;
    bench_comp_config(&cfg);

#if defined(BENCH_F32)
    warm_f32(40u);
    plan("eq3_f32", N);
    for (uint32_t i = 0; i < N; i++) eval_f32(i, 0);
    plan("eq3_thermal_f32", N);
    for (uint32_t i = 0; i < N; i++) eval_f32(i, 1);
    plan("apply_f32", N);
    for (uint32_t i = 0; i < N; i++) {
        float e[3] = {0.0f, 0.0f, 0.0f};
        abbe_thermal_update_f32(&st, S[48u + i].x, 0x1FFFFu, S[48u + i].dt_s);
        bench_mark();
        abbe_thermal_apply_f32(&st, e);
        bench_mark();
        sink = (int32_t)e[0];
    }
    /* while fading: a period of 1 s, the fade takes 30 calls */
    abbe_thermal_init_f32(&st, &tm, 1.0f);
    abbe_thermal_update_f32(&st, S[0].x, 0x1FFFFu, 0.0f);
    plan("apply_fading_f32", N);
    for (uint32_t i = 0; i < N; i++) {
        float e[3] = {0.0f, 0.0f, 0.0f};
        bench_mark();
        abbe_thermal_apply_f32(&st, e);
        bench_mark();
        sink = (int32_t)e[0];
    }
    warm_f32(40u);
    plan("update_f32", N);
    for (uint32_t i = 0; i < N; i++) {
        uint32_t n = 40u + i;
        bench_mark();
        abbe_thermal_update_f32(&st, S[n].x, 0x1FFFFu, S[n].dt_s);
        bench_mark();
    }
    abbe_comp_init(&comp, &cfg, &model);
    abbe_comp_enable(&comp);
    plan("comp_f32", N);
    for (uint32_t i = 0; i < N + 4u; i++) {
        abbe_comp_output_t out;
        int32_t pos_nm[ABBE_AXES];
        bench_path_nm(i, pos_nm);
        abbe_comp_input_f32_t in = {{(float)pos_nm[0] * 1e-6f, (float)pos_nm[1] * 1e-6f, (float)pos_nm[2] * 1e-6f},
                                    {20.0f, 20.0f, 20.0f}, {1, -1, -1}, 1, 0};
        if (i >= 4u) bench_mark();
        abbe_comp_step_f32(&comp, &in, &out);
        if (i >= 4u) bench_mark();
        sink = out.corr_nm[0];
    }
    warm_f32(40u);
    abbe_comp_init(&comp, &cfg, &model);
    abbe_comp_enable(&comp);
    plan("comp_thermal_f32", N);
    for (uint32_t i = 0; i < N + 4u; i++) {
        abbe_comp_output_t out;
        int32_t pos_nm[ABBE_AXES];
        bench_path_nm(i, pos_nm);
        abbe_comp_input_f32_t in = {{(float)pos_nm[0] * 1e-6f, (float)pos_nm[1] * 1e-6f, (float)pos_nm[2] * 1e-6f},
                                    {20.0f, 20.0f, 20.0f}, {1, -1, -1}, 1, 0};
        abbe_thermal_update_f32(&st, S[40u + i].x, 0x1FFFFu, S[40u + i].dt_s);
        if (i >= 4u) bench_mark();
        abbe_comp_step_thermal_f32(&comp, &st, &in, &out);
        if (i >= 4u) bench_mark();
        sink = out.corr_nm[0];
    }
#endif
#if defined(BENCH_Q)
    warm_q(40u);
    plan("eq3_q", N);
    for (uint32_t i = 0; i < N; i++) eval_q(i, 0);
    plan("eq3_thermal_q", N);
    for (uint32_t i = 0; i < N; i++) eval_q(i, 1);
    plan("apply_q", N);
    for (uint32_t i = 0; i < N; i++) {
        int32_t e[3] = {0, 0, 0};
        abbe_thermal_update_q(&st, S[48u + i].x_milli, 0x1FFFFu, 15000u);
        bench_mark();
        abbe_thermal_apply_q(&st, e);
        bench_mark();
        sink = e[0];
    }
    abbe_thermal_init_q(&st, &tm, 1000000u);
    abbe_thermal_update_q(&st, S[0].x_milli, 0x1FFFFu, 0u);
    plan("apply_fading_q", N);
    for (uint32_t i = 0; i < N; i++) {
        int32_t e[3] = {0, 0, 0};
        bench_mark();
        abbe_thermal_apply_q(&st, e);
        bench_mark();
        sink = e[0];
    }
    warm_q(40u);
    plan("update_q", N); /* the same dt as before: cached weights */
    for (uint32_t i = 0; i < N; i++) {
        uint32_t n = 40u + i;
        bench_mark();
        abbe_thermal_update_q(&st, S[n].x_milli, 0x1FFFFu, 15000u);
        bench_mark();
    }
    plan("update_q_new_dt", N); /* a new dt each time: 20 weights recomputed (64-bit divisions) */
    for (uint32_t i = 0; i < N; i++) {
        uint32_t n = 48u + i;
        bench_mark();
        abbe_thermal_update_q(&st, S[n].x_milli, 0x1FFFFu, S[n].dt_ms + i);
        bench_mark();
    }
    abbe_comp_init(&comp, &cfg, &model);
    abbe_comp_enable(&comp);
    plan("comp_q", N);
    for (uint32_t i = 0; i < N + 4u; i++) {
        abbe_comp_output_t out;
        int32_t pos_nm[ABBE_AXES];
        bench_path_nm(i, pos_nm);
        abbe_comp_input_q_t in = {{pos_nm[0], pos_nm[1], pos_nm[2]}, {20000, 20000, 20000}, {1, -1, -1}, 1, 0};
        if (i >= 4u) bench_mark();
        abbe_comp_step_q(&comp, &in, &out);
        if (i >= 4u) bench_mark();
        sink = out.corr_nm[0];
    }
    warm_q(40u);
    abbe_comp_init(&comp, &cfg, &model);
    abbe_comp_enable(&comp);
    plan("comp_thermal_q", N);
    for (uint32_t i = 0; i < N + 4u; i++) {
        abbe_comp_output_t out;
        int32_t pos_nm[ABBE_AXES];
        bench_path_nm(i, pos_nm);
        abbe_comp_input_q_t in = {{pos_nm[0], pos_nm[1], pos_nm[2]}, {20000, 20000, 20000}, {1, -1, -1}, 1, 0};
        abbe_thermal_update_q(&st, S[40u + i].x_milli, 0x1FFFFu, 15000u);
        if (i >= 4u) bench_mark();
        abbe_comp_step_thermal_q(&comp, &st, &in, &out);
        if (i >= 4u) bench_mark();
        sink = out.corr_nm[0];
    }
#endif
    sh_puts("DONE\n");
    return 0;
}

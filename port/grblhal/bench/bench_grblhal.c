/* Cortex-M benchmark of the grblHAL plugin's core: exact instruction counts
 * per call under QEMU (bench/bench_target.c's method: every measured call
 * between two bench_mark() calls, PLAN lines name them; scripts/bench_report.py
 * counts the trace lines between marks minus an empty pair).
 *
 * Per segment the plugin runs abbe_gh_line_next() (the segment end on the
 * Cartesian line) and abbe_gh_forward() (one compensator step: the
 * transform_from_cartesian of the segment end). Measured along the vmc500
 * ballbar circle (r = 100 mm, 0.9 mm chords, grblHAL's own arc segmentation)
 * and along a 300 mm diagonal line split into segments of the table's length.
 * Also: abbe_gh_line_begin() per line and abbe_gh_inverse() per position
 * report. The table is abbe_model.c (abbe table cgen) of the vmc500 fit;
 * M4F runs _f32, M3 _q (ABBE_GH_FIXED_POINT follows __ARM_FP).
 *
 * With ABBE_GH_BENCH_THERMAL the table carries a thermal block (format 1.3,
 * examples/spindle_thermal/thermal.json: 17 inputs, 5 channels): the clock
 * advances 1 s per fade-in segment with a sample every 10 s, then 100 ms per
 * measured segment (a sample every 15 s is far rarer than segments), so each
 * measured segment end adds the thermal error by elapsed time
 * (abbe_comp_step_thermal_ms_*); and abbe_gh_thermal_sample() of the 17
 * inputs is measured at the end. */
#include <stdint.h>

#include "abbe_grblhal_core.h"
#include "abbe_model.h"
#include "semihost.h"

#define CIRCLE_POINTS 16u
#define LINE_SEGMENTS 16u

static abbe_gh_t gh;
static volatile int32_t sink;

#ifdef ABBE_GH_BENCH_THERMAL
static uint32_t clock_ms;
static float th_x[17];

/* A warm machine's sample: every temperature 0.5 K above its reference (the
 * block's, read from the running model) and moving by k mK, 3000 rpm. */
static void th_sample(uint32_t k)
{
    const abbe_thermal_state_t *ts = abbe_gh_thermal(&gh);
    for (uint32_t i = 0; i < 16u; i++) {
        float ref = ts != 0 ? (float)ts->model->ref_milli[i] * 0.001f : 20.0f;
        th_x[i] = ref + 0.5f + 0.001f * (float)k;
    }
    th_x[16] = 3000.0f;
    const char *why = 0;
    sink = (int32_t)abbe_gh_thermal_sample(&gh, th_x, 0x1FFFFu, &why);
}

static void tick(uint32_t ms)
{
    clock_ms += ms;
    abbe_gh_clock(&gh, clock_ms);
}
#else
static void tick(uint32_t ms)
{
    (void)ms;
}
#endif

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

/* cos / sin of k * 2 pi / 700 by rotation (no libm): the circle's chord ends. */
static void circle_point(uint32_t k, float out[3])
{
    static const float c1 = 0.99995971f, s1 = 0.00897587f; /* cos, sin of 2 pi / 700 */
    float c = 1.0f, s = 0.0f;
    for (uint32_t i = 0; i < k; i++) {
        float cn = c * c1 - s * s1;
        s = s * c1 + c * s1;
        c = cn;
    }
    out[0] = 343.507f + 100.0f * c;
    out[1] = -285.09f + 100.0f * s;
    out[2] = -286.43f;
}

int main(void)
{
    abbe_gh_params_t p;
    abbe_gh_default_params(&p);
    if (abbe_gh_init(&gh, &p, abbe_model_blob, abbe_model_blob_size) != ABBE_OK) {
        sh_puts("bench_grblhal: table refused\n");
        return 1;
    }
    (void)abbe_gh_set_enabled(&gh, 1);
    float cart[3], motor[3], back[3];

    plan("calibration", 1u);
    bench_mark();
    bench_mark();

#ifdef ABBE_GH_BENCH_THERMAL
    tick(1u);
    th_sample(0u);
#endif
    /* Fade in on the circle first (32 segments; the thermal part: 1 s per
     * segment, faded in after its fade time), then measure full-gain steps. */
    for (uint32_t k = 0; k < 40u; k++) {
        tick(1000u);
#ifdef ABBE_GH_BENCH_THERMAL
        if (k % 10u == 9u) {
            th_sample(k);
        }
#endif
        circle_point(k, cart);
        (void)abbe_gh_forward(&gh, cart, motor);
    }
#ifdef ABBE_GH_BENCH_THERMAL
    {
        const abbe_thermal_state_t *ts = abbe_gh_thermal(&gh);
        sh_puts("THERMAL_FLAGS ");
        sh_put_u32(ts != 0 ? abbe_thermal_flags(ts) : 0xFFFFFFFFu);
        sh_puts("\n");
    }
#endif
    plan("forward_circle", CIRCLE_POINTS);
    for (uint32_t k = 40u; k < 40u + CIRCLE_POINTS; k++) {
        tick(100u);
        circle_point(k, cart);
        bench_mark();
        sink = (int32_t)abbe_gh_forward(&gh, cart, motor);
        bench_mark();
    }

    /* A line: begin, then next + forward per segment. */
    abbe_gh_line_t line;
    float start[3] = {gh.last_cart[0], gh.last_cart[1], gh.last_cart[2]};
    float end[3] = {start[0] - 150.0f, start[1] + 150.0f, start[2] + 200.0f};
    plan("line_begin", 1u);
    bench_mark();
    uint32_t n = abbe_gh_line_begin(&gh, &line, start, end);
    bench_mark();
    sh_puts("SEGMENTS ");
    sh_put_u32(n);
    sh_puts("\n");
    plan("line_next", LINE_SEGMENTS);
    plan("forward_line", LINE_SEGMENTS);
    for (uint32_t k = 0; k < LINE_SEGMENTS; k++) {
        bench_mark();
        (void)abbe_gh_line_next(&line, cart);
        bench_mark();
    }
    /* second pass: forward along the same segment ends (plan order: all
     * line_next marks come first) */
    (void)abbe_gh_line_begin(&gh, &line, start, end);
    for (uint32_t k = 0; k < LINE_SEGMENTS; k++) {
        (void)abbe_gh_line_next(&line, cart);
        tick(100u);
        bench_mark();
        sink = (int32_t)abbe_gh_forward(&gh, cart, motor);
        bench_mark();
    }

    plan("inverse", 4u);
    for (uint32_t k = 0; k < 4u; k++) {
        bench_mark();
        sink = abbe_gh_inverse(&gh, motor, back);
        bench_mark();
    }
#ifdef ABBE_GH_BENCH_THERMAL
    plan("thermal_sample", 4u);
    for (uint32_t k = 0; k < 4u; k++) {
        tick(15000u);
        bench_mark();
        th_sample(100u + k);
        bench_mark();
    }
#endif
    sh_puts("DONE\n");
    return 0;
}

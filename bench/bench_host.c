/* Host benchmark driver, run under valgrind --tool=callgrind by
 * scripts/bench_report.py (instruction counts, not time).
 *
 *   bench_host MODE N [TABLE]
 *                         MODE: f32 f32_base q comp_f32 comp_q naive lean empty
 *                         runs N calls over the "paper" golden table's points
 *                         (f32_base: the x86-64 SSE2 kernels whatever the CPU
 *                         has; lean: the lean reference evaluator, lean_ref.c),
 *                         or over TABLE's (another golden table: "backlash",
 *                         "reversal"; exit 3 if this library refuses it)
 *   bench_host check      naive reference against the golden vectors and the
 *                         library (prints max abs differences, exit 1 if the
 *                         naive reference is off by more than 2 nm)
 */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "bench_common.h"
#include "lean_ref.h"
#include "naive_ref.h"

/* The naive evaluator at a golden point's f32 input (the same float values). */
static void naive_eval_point(const naive_model_t *nm, const abbe_golden_point_t *p, double err[3])
{
    double pos[3], dir[3], temp[3];
    for (int j = 0; j < 3; j++) {
        pos[j] = p->pos_mm[j];
        dir[j] = p->dir_state[j];
        temp[j] = p->temp_c[j];
    }
    naive_eval(nm, pos, dir, temp, err);
}

static volatile float sink_f;
static volatile int32_t sink_i;
static volatile double sink_d;

/* An empty call with the signature of an evaluation: the loop's own cost. */
__attribute__((noinline)) abbe_status_t bench_empty(const abbe_model_t *m, const abbe_input_f32_t *in,
                                                    abbe_error_f32_t *out)
{
    __asm__ volatile("" ::"r"(m), "r"(in), "r"(out) : "memory");
    return ABBE_OK;
}

static int check(const abbe_model_t *model, const abbe_golden_table_t *paper)
{
    double worst_golden = 0.0, worst_lib = 0.0;
    for (uint32_t t = 0; t < abbe_golden_table_count; t++) {
        const abbe_golden_table_t *gt = &abbe_golden_tables[t];
        naive_model_t nm;
        if (naive_load(&nm, gt->blob, gt->blob_size) != 0) {
            printf("naive_load failed on '%s'\n", gt->name);
            return 1;
        }
        double table_worst = 0.0;
        for (uint32_t i = gt->first_point; i < gt->first_point + gt->n_points; i++) {
            const abbe_golden_point_t *p = &abbe_golden_points[i];
            double err[3];
            naive_eval_point(&nm, p, err);
            for (int j = 0; j < 3; j++) {
                double d = fabs(err[j] * 1e6 - p->expect_f32_pm[j]);
                table_worst = d > table_worst ? d : table_worst;
            }
        }
        printf("naive vs golden '%s': max |diff| %.0f pm\n", gt->name, table_worst);
        worst_golden = table_worst > worst_golden ? table_worst : worst_golden;
    }
    naive_model_t nm;
    naive_load(&nm, paper->blob, paper->blob_size);
    for (uint32_t k = 0; k < 1000; k++) {
        int32_t pos_nm[3];
        abbe_input_f32_t in;
        abbe_error_f32_t out;
        double pos[3], dir[3] = {0, 0, 0}, temp[3] = {20, 20, 20}, err[3];
        bench_path_nm(k * 60u, pos_nm);
        for (int j = 0; j < 3; j++) {
            in.pos_mm[j] = (float)pos_nm[j] * 1e-6f;
            in.dir_state[j] = 0.0f;
            in.temp_c[j] = 20.0f;
            pos[j] = in.pos_mm[j];
        }
        abbe_error_eval_f32(model, &in, &out);
        naive_eval(&nm, pos, dir, temp, err);
        for (int j = 0; j < 3; j++) {
            double d = fabs((double)out.error_um[j] - err[j]) * 1e6;
            worst_lib = d > worst_lib ? d : worst_lib;
        }
    }
    printf("naive vs abbe_error_eval_f32 ('%s', 1000 path points): max |diff| %.0f pm\n",
           paper->name, worst_lib);
    /* the lean reference leaves the tool offset out (and reduces phases in
     * float): how far that is from the model, for the record */
    lean_model_t lm;
    double worst_lean = 0.0;
    lean_load(&lm, paper->blob, paper->blob_size);
    for (uint32_t i = paper->first_point; i < paper->first_point + paper->n_points; i++) {
        const abbe_golden_point_t *p = &abbe_golden_points[i];
        float err[3];
        if (p->expect_flags != 0u) {
            continue; /* outside the travel: the lean evaluator does not clamp */
        }
        lean_eval(&lm, p->pos_mm, err);
        for (int j = 0; j < 3; j++) {
            double d = fabs((double)err[j] * 1e6 - p->expect_f32_pm[j]);
            worst_lean = d > worst_lean ? d : worst_lean;
        }
    }
    printf("lean reference vs golden '%s', points in the travel (tool offset left out): max |diff| %.0f pm\n",
           paper->name, worst_lean);
    return worst_golden <= ABBE_GOLDEN_TOL_PM ? 0 : 1;
}

int main(int argc, char **argv)
{
    const abbe_golden_table_t *paper = bench_table();
    abbe_model_t model;
    if (paper == NULL || abbe_model_load(&model, paper->blob, paper->blob_size) != ABBE_OK) {
        fprintf(stderr, "bench_host: cannot load the '%s' golden table\n", BENCH_TABLE);
        return 2;
    }
    if (argc == 4) { /* another golden table: its points and its model */
        paper = bench_table_named(argv[3]);
        if (paper == NULL) {
            fprintf(stderr, "bench_host: no golden table '%s'\n", argv[3]);
            return 2;
        }
        if (abbe_model_load(&model, paper->blob, paper->blob_size) != ABBE_OK) {
            fprintf(stderr, "bench_host: this library refuses the '%s' table\n", argv[3]);
            return 3;
        }
        argc = 3;
    }
    if (argc == 2 && strcmp(argv[1], "check") == 0) {
#if defined(__x86_64__)
        printf("x86-64 f32 kernels on this CPU: %s\n",
               model.simd ? "x86-64-v3 (AVX2, FMA)" : "SSE2 (or plain C if built with ABBE_PORTABLE_C)");
#endif
        return check(&model, paper);
    }
    if (argc != 3) {
        fprintf(stderr, "usage: bench_host f32|f32_base|q|comp_f32|comp_q|naive|lean|empty N [TABLE] | check\n");
        return 2;
    }
    const char *mode = argv[1];
    const uint32_t n = (uint32_t)strtoul(argv[2], NULL, 10);
    const uint32_t np = paper->n_points;
    const abbe_golden_point_t *pts = &abbe_golden_points[paper->first_point];

    if (strcmp(mode, "f32_base") == 0) {
        /* x86-64: the SSE2 kernels every x86-64 runs, whatever this CPU has
         * (model.simd is what abbe_model_load() found: 1 = x86-64-v3) */
        model.simd = 0;
        mode = "f32";
    }
    if (strcmp(mode, "f32") == 0 || strcmp(mode, "empty") == 0) {
        abbe_input_f32_t *in = calloc(np, sizeof *in);
        for (uint32_t i = 0; i < np; i++) {
            memcpy(in[i].pos_mm, pts[i].pos_mm, sizeof in[i].pos_mm);
            memcpy(in[i].dir_state, pts[i].dir_state, sizeof in[i].dir_state);
            memcpy(in[i].temp_c, pts[i].temp_c, sizeof in[i].temp_c);
        }
        abbe_status_t (*fn)(const abbe_model_t *, const abbe_input_f32_t *, abbe_error_f32_t *) =
            strcmp(mode, "f32") == 0 ? abbe_error_eval_f32 : bench_empty;
        for (uint32_t k = 0; k < n; k++) {
            abbe_error_f32_t out;
            fn(&model, &in[k % np], &out);
            sink_f = out.error_um[0];
        }
        free(in);
    } else if (strcmp(mode, "q") == 0) {
        abbe_input_q_t *in = calloc(np, sizeof *in);
        for (uint32_t i = 0; i < np; i++) {
            memcpy(in[i].pos_nm, pts[i].pos_nm, sizeof in[i].pos_nm);
            memcpy(in[i].dir_state_q30, pts[i].dir_q30, sizeof in[i].dir_state_q30);
            memcpy(in[i].temp_mdegc, pts[i].temp_mdegc, sizeof in[i].temp_mdegc);
        }
        for (uint32_t k = 0; k < n; k++) {
            abbe_error_q_t out;
            abbe_error_eval_q(&model, &in[k % np], &out);
            sink_i = out.error_nm[0];
        }
        free(in);
    } else if (strcmp(mode, "lean") == 0) {
        lean_model_t lm;
        lean_load(&lm, paper->blob, paper->blob_size);
        for (uint32_t k = 0; k < n; k++) {
            float err[3];
            lean_eval(&lm, pts[k % np].pos_mm, err);
            sink_f = err[0];
        }
    } else if (strcmp(mode, "naive") == 0) {
        naive_model_t nm;
        naive_load(&nm, paper->blob, paper->blob_size);
        for (uint32_t k = 0; k < n; k++) {
            const abbe_golden_point_t *p = &pts[k % np];
            double err[3];
            naive_eval_point(&nm, p, err);
            sink_d = err[0];
        }
    } else if (strcmp(mode, "comp_f32") == 0 || strcmp(mode, "comp_q") == 0) {
        const int use_q = strcmp(mode, "comp_q") == 0;
        abbe_comp_config_t cfg;
        abbe_comp_t comp;
        abbe_comp_output_t out;
        bench_comp_config(&cfg);
        abbe_comp_init(&comp, &cfg, &model);
        abbe_comp_enable(&comp);
        for (uint32_t k = 0; k < n + 4u; k++) { /* 4 cycles to fade in */
            int32_t pos_nm[3];
            bench_path_nm(k, pos_nm);
            if (use_q) {
                abbe_comp_input_q_t in = {{pos_nm[0], pos_nm[1], pos_nm[2]},
                                          {20000, 20000, 20000}, {1, -1, -1}, 1, 0};
                abbe_comp_step_q(&comp, &in, &out);
            } else {
                abbe_comp_input_f32_t in = {{(float)pos_nm[0] * 1e-6f, (float)pos_nm[1] * 1e-6f,
                                             (float)pos_nm[2] * 1e-6f},
                                            {20.0f, 20.0f, 20.0f}, {1, -1, -1}, 1, 0};
                abbe_comp_step_f32(&comp, &in, &out);
            }
            sink_i = out.corr_nm[0];
        }
        if (out.state != ABBE_COMP_ON || out.flags != 0u) {
            fprintf(stderr, "bench_host: compensator not in steady state (state %d flags 0x%x)\n",
                    (int)out.state, (unsigned)out.flags);
            return 1;
        }
    } else {
        fprintf(stderr, "bench_host: unknown mode '%s'\n", mode);
        return 2;
    }
    return 0;
}

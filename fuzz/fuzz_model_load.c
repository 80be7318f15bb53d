/* libFuzzer harness: abbe_model_load() on arbitrary bytes, and when a blob
 * loads, both evaluation variants, every single term and a few compensator
 * cycles at a fixed set of positions plus positions taken from the bytes after
 * the table's total_size (which the loader must ignore).
 *
 * Each input is tried as it is and, when its total_size is plausible, with
 * its CRC fixed up, so that mutations get past the CRC check.
 *
 * Checked beyond "no sanitizer report":
 *   - a failed load leaves the model untouched;
 *   - a loaded model reports a size <= the input length and a CRC that matches;
 *   - finite, in-range inputs evaluate to ABBE_OK; f32 results are finite;
 *   - the total reversal of every axis (format 1.1 blocks) is finite and within
 *     the loader's cap;
 *   - out-of-range axis/term arguments give ABBE_E_ARG.
 */
#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "abbe/abbe.h"
#include "fuzz_table_input.h"

#define CHECK(cond)                                                                      \
    do {                                                                                 \
        if (!(cond)) {                                                                   \
            fprintf(stderr, "fuzz_model_load: check failed: %s (line %d)\n", #cond,       \
                    __LINE__);                                                           \
            abort();                                                                     \
        }                                                                                \
    } while (0)

static uint32_t ld_u32(const uint8_t *p)
{
    return (uint32_t)p[0] | ((uint32_t)p[1] << 8) | ((uint32_t)p[2] << 16) |
           ((uint32_t)p[3] << 24);
}

static void eval_at(const abbe_model_t *m, const int32_t pos_nm[3], int32_t dir_q30,
                    int32_t temp_mdegc, int check_finite)
{
    abbe_input_q_t iq;
    abbe_error_q_t oq;
    for (unsigned j = 0; j < ABBE_AXES; j++) {
        iq.pos_nm[j] = pos_nm[j];
        iq.dir_state_q30[j] = dir_q30;
        iq.temp_mdegc[j] = temp_mdegc;
    }
    CHECK(abbe_error_eval_q(m, &iq, &oq) == ABBE_OK);

    abbe_input_f32_t inf;
    abbe_error_f32_t of;
    for (unsigned j = 0; j < ABBE_AXES; j++) {
        inf.pos_mm[j] = (float)pos_nm[j] * 1e-6f;
        inf.dir_state[j] = (float)dir_q30 / (float)ABBE_DIR_Q30_ONE;
        inf.temp_c[j] = (float)temp_mdegc * 1e-3f;
    }
    CHECK(abbe_error_eval_f32(m, &inf, &of) == ABBE_OK);
    if (check_finite) {
        for (unsigned j = 0; j < ABBE_AXES; j++) {
            CHECK(isfinite(of.error_um[j]));
        }
    }

    for (unsigned axis = 0; axis < ABBE_AXES; axis++) {
        for (unsigned term = 0; term < ABBE_TERMS; term++) {
            float v = 0.0f;
            int32_t vq = 0;
            CHECK(abbe_term_eval_f32(m, axis, term, inf.pos_mm[axis], &v) == ABBE_OK);
            CHECK(isfinite(v));
            CHECK(abbe_term_eval_q(m, axis, term, pos_nm[axis], &vq) == ABBE_OK);
        }
        /* the total reversal (format 1.1 blocks): finite and within the
         * loader's cap |B| + sum |r_k| <= 2^31 x 2^-8 nm */
        float r = 0.0f;
        int32_t rq = 0;
        CHECK(abbe_reversal_eval_f32(m, axis, inf.pos_mm[axis], &r) == ABBE_OK);
        CHECK(isfinite(r) && fabsf(r) <= 8400.0f); /* um: 2^31 x 2^-8 nm = 8389 um */
        CHECK(abbe_reversal_eval_q(m, axis, pos_nm[axis], &rq) == ABBE_OK);
    }
}

static void run_comp(const abbe_model_t *m, const int32_t pos_nm[3])
{
    abbe_comp_config_t cfg;
    abbe_comp_t comp;
    abbe_comp_output_t out;
    memset(&cfg, 0, sizeof cfg);
    for (unsigned j = 0; j < ABBE_AXES; j++) {
        cfg.warn_nm[j] = 50000;
        cfg.limit_nm[j] = 200000;
        cfg.rate_nm_per_cycle[j] = 1000;
        cfg.axis_sign[j] = (int8_t)(j == 1 ? -1 : 1);
    }
    cfg.fade_cycles = 4;
    cfg.stale_cycles = 3;
    CHECK(abbe_comp_init(&comp, &cfg, m) == ABBE_OK);
    CHECK(abbe_comp_enable(&comp) == ABBE_OK);
    for (int cycle = 0; cycle < 8; cycle++) {
        abbe_comp_input_q_t iq;
        abbe_comp_input_f32_t inf;
        for (unsigned j = 0; j < ABBE_AXES; j++) {
            iq.pos_nm[j] = pos_nm[j] + cycle * 1000;
            iq.temp_mdegc[j] = 20000;
            iq.dir[j] = (int8_t)((cycle & 2) ? -1 : 1);
            inf.pos_mm[j] = (float)iq.pos_nm[j] * 1e-6f;
            inf.temp_c[j] = 20.0f;
            inf.dir[j] = iq.dir[j];
        }
        iq.fresh = inf.fresh = (uint8_t)(cycle != 5);
        iq.axis_fault_mask = inf.axis_fault_mask = 0;
        if (cycle & 1) {
            CHECK(abbe_comp_step_f32(&comp, &inf, &out) == ABBE_OK);
        } else {
            CHECK(abbe_comp_step_q(&comp, &iq, &out) == ABBE_OK);
        }
        for (unsigned j = 0; j < ABBE_AXES; j++) {
            CHECK(out.corr_nm[j] <= cfg.limit_nm[j] && out.corr_nm[j] >= -cfg.limit_nm[j]);
        }
    }
}

static void exercise(const uint8_t *data, size_t size)
{
    abbe_model_t model;
    abbe_model_t before;
    memset(&model, 0x5A, sizeof model);
    before = model;

    abbe_status_t st = abbe_model_load(&model, data, size);
    CHECK(st <= ABBE_OK && st >= ABBE_STATUS_MIN);
    CHECK(abbe_strerror(st) != NULL);
    if (st != ABBE_OK) {
        CHECK(memcmp(&model, &before, sizeof model) == 0);
        return;
    }
    const uint32_t total = abbe_model_size(&model);
    CHECK(total >= 260u && total <= size && total == ld_u32(data + 8));
    CHECK(abbe_model_crc(&model) == ld_u32(data + total - 4u));
    CHECK(abbe_crc32(0u, data, total - 4u) == abbe_model_crc(&model));

    /* Fixed positions: origin, +/-1 m, the +/-2.147 m extremes, odd values. */
    static const int32_t fixed[][3] = {
        {0, 0, 0},
        {1000000000, -1000000000, 500000000},
        {INT32_MAX, INT32_MIN, INT32_MAX},
        {INT32_MIN, INT32_MAX, -1},
        {123456789, -98765432, 31415926},
    };
    for (size_t i = 0; i < sizeof fixed / sizeof fixed[0]; i++) {
        eval_at(&model, fixed[i], (i & 1u) ? -ABBE_DIR_Q30_ONE : ABBE_DIR_Q30_ONE,
                20000 + (int32_t)i * 5000, 1);
    }

    /* Positions from the bytes after the table (ignored by the loader). */
    const uint8_t *extra = data + total;
    size_t n_extra = size - total;
    for (size_t k = 0; k + 12u <= n_extra && k < 12u * 8u; k += 12u) {
        int32_t pos[3];
        for (unsigned j = 0; j < 3; j++) {
            uint32_t u = ld_u32(extra + k + 4u * j);
            memcpy(&pos[j], &u, sizeof u);
        }
        eval_at(&model, pos, 0, 20000, 1);
    }

    /* Range errors of the single-term API. */
    float v;
    int32_t vq;
    CHECK(abbe_term_eval_f32(&model, ABBE_AXES, 0, 0.0f, &v) == ABBE_E_ARG);
    CHECK(abbe_term_eval_q(&model, 0, ABBE_TERMS, 0, &vq) == ABBE_E_ARG);
    CHECK(abbe_reversal_eval_f32(&model, ABBE_AXES, 0.0f, &v) == ABBE_E_ARG);
    CHECK(abbe_reversal_eval_q(&model, ABBE_AXES, 0, &vq) == ABBE_E_ARG);
    {
        abbe_input_f32_t nan_in = {{NAN, 0.0f, 0.0f}, {0.0f, 0.0f, 0.0f}, {20.0f, 20.0f, 20.0f}};
        abbe_error_f32_t of;
        CHECK(abbe_error_eval_f32(&model, &nan_in, &of) == ABBE_E_INPUT);
    }

    run_comp(&model, fixed[4]);
}

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    fz_table_input(data, size, exercise);
    return 0;
}

/* libFuzzer harness: abbe_five_model_load() (format 1.2, five-axis tables) on
 * arbitrary bytes, each input also with its CRC fixed up; when a table loads,
 * both five-axis evaluations at fixed joint positions and at positions and
 * angles taken from the bytes after the table, and compensator cycles.
 *
 * Checked beyond "no sanitizer report":
 *   - a failed load leaves the model untouched;
 *   - abbe_model_load() accepts exactly the loadable tables without the rotary
 *     section (ROTARY bit clear), and then both loaders evaluate the same
 *     position error (no rotary errors);
 *   - finite inputs evaluate to ABBE_OK with finite f32 results; a NaN angle
 *     is ABBE_E_INPUT;
 *   - compensator outputs stay within the configured limit.
 */
#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "abbe/abbe.h"
#include "fuzz_table_input.h"

#define CHECK(cond)                                                                                  \
    do {                                                                                             \
        if (!(cond)) {                                                                               \
            fprintf(stderr, "fuzz_five_load: check failed: %s (line %d)\n", #cond, __LINE__);        \
            abort();                                                                                 \
        }                                                                                            \
    } while (0)

static uint32_t ld_u32(const uint8_t *p)
{
    return (uint32_t)p[0] | ((uint32_t)p[1] << 8) | ((uint32_t)p[2] << 16) | ((uint32_t)p[3] << 24);
}

static void eval_at(const abbe_five_model_t *m, const abbe_model_t *m3, const int32_t pos_nm[3],
                    const int32_t udeg[2])
{
    abbe_five_input_q_t iq;
    abbe_five_error_q_t oq;
    memset(&iq, 0, sizeof iq);
    memcpy(iq.pos_nm, pos_nm, sizeof iq.pos_nm);
    memcpy(iq.angle_udeg, udeg, sizeof iq.angle_udeg);
    for (unsigned j = 0; j < 3u; j++) {
        iq.temp_mdegc[j] = 20000;
    }
    CHECK(abbe_five_error_eval_q(m, &iq, &oq) == ABBE_OK);
    if (m3 != NULL) {
        abbe_input_q_t i3;
        abbe_error_q_t o3;
        memcpy(i3.pos_nm, iq.pos_nm, sizeof i3.pos_nm);
        memcpy(i3.dir_state_q30, iq.dir_state_q30, sizeof i3.dir_state_q30);
        memcpy(i3.temp_mdegc, iq.temp_mdegc, sizeof i3.temp_mdegc);
        CHECK(abbe_error_eval_q(m3, &i3, &o3) == ABBE_OK);
        CHECK(memcmp(o3.error_nm, oq.error_nm, sizeof o3.error_nm) == 0);
    }
    abbe_five_input_f32_t inf;
    abbe_five_error_f32_t of;
    memset(&inf, 0, sizeof inf);
    for (unsigned j = 0; j < 3u; j++) {
        inf.pos_mm[j] = (float)pos_nm[j] * 1e-6f;
        inf.temp_c[j] = 20.0f;
    }
    inf.angle_deg[0] = (float)udeg[0] * 1e-6f;
    inf.angle_deg[1] = (float)udeg[1] * 1e-6f;
    CHECK(abbe_five_error_eval_f32(m, &inf, &of) == ABBE_OK);
    for (unsigned j = 0; j < 3u; j++) {
        CHECK(isfinite(of.error_um[j]) && isfinite(of.orient_urad[j]));
    }
    inf.angle_deg[1] = NAN;
    CHECK(abbe_five_error_eval_f32(m, &inf, &of) == ABBE_E_INPUT);
}

static void run_comp(const abbe_five_model_t *m)
{
    abbe_comp_config_t cfg;
    abbe_comp_t comp;
    abbe_comp_output5_t out;
    memset(&cfg, 0, sizeof cfg);
    for (unsigned j = 0; j < 3u; j++) {
        cfg.warn_nm[j] = 50000;
        cfg.limit_nm[j] = 200000;
        cfg.rate_nm_per_cycle[j] = 1000;
        cfg.axis_sign[j] = (int8_t)(j == 1 ? -1 : 1);
    }
    cfg.fade_cycles = 4;
    cfg.stale_cycles = 3;
    CHECK(abbe_comp_init(&comp, &cfg, NULL) == ABBE_OK);
    CHECK(abbe_comp_swap_five_model(&comp, m) == ABBE_OK);
    CHECK(abbe_comp_enable(&comp) == ABBE_OK);
    for (int cycle = 0; cycle < 8; cycle++) {
        abbe_comp_input5_q_t iq;
        abbe_comp_input5_f32_t inf;
        memset(&iq, 0, sizeof iq);
        memset(&inf, 0, sizeof inf);
        for (unsigned j = 0; j < 3u; j++) {
            iq.lin.pos_nm[j] = 100000000 + cycle * 1000;
            iq.lin.temp_mdegc[j] = 20000;
            inf.lin.pos_mm[j] = (float)iq.lin.pos_nm[j] * 1e-6f;
            inf.lin.temp_c[j] = 20.0f;
        }
        iq.angle_udeg[0] = cycle * 15000000;
        iq.angle_udeg[1] = cycle * 45000000;
        inf.angle_deg[0] = (float)cycle * 15.0f;
        inf.angle_deg[1] = (float)cycle * 45.0f;
        iq.lin.fresh = inf.lin.fresh = (uint8_t)(cycle != 5);
        if (cycle & 1) {
            CHECK(abbe_comp_step5_f32(&comp, &inf, &out) == ABBE_OK);
        } else {
            CHECK(abbe_comp_step5_q(&comp, &iq, &out) == ABBE_OK);
        }
        for (unsigned j = 0; j < 3u; j++) {
            CHECK(out.lin.corr_nm[j] <= cfg.limit_nm[j] && out.lin.corr_nm[j] >= -cfg.limit_nm[j]);
        }
    }
}

static void exercise(const uint8_t *data, size_t size)
{
    static abbe_five_model_t model, before;
    static abbe_model_t m3;
    memset(&model, 0x5A, sizeof model);
    before = model;
    abbe_status_t st = abbe_five_model_load(&model, data, size);
    CHECK(st <= ABBE_OK && st >= ABBE_STATUS_MIN);
    abbe_status_t st3 = abbe_model_load(&m3, data, size);
    if (st != ABBE_OK) {
        CHECK(memcmp(&model, &before, sizeof model) == 0);
        CHECK(st3 != ABBE_OK); /* the five-axis loader reads every 3-axis table */
        return;
    }
    const uint32_t total = ld_u32(data + 8);
    const int rotary = (ld_u32(data + 20) & ABBE_FEATURE_ROTARY) != 0u;
    /* the 3-axis loader reads exactly the tables of minor <= 1 (a 1.2 table is
     * refused by its minor even without ROTARY: the minor is what the writer
     * declared the table needs) */
    const unsigned minor = (unsigned)data[6] | ((unsigned)data[7] << 8);
    CHECK((st3 == ABBE_OK) == (!rotary && minor <= 1u));
    CHECK((abbe_five_model_kind(&model) == ABBE_KIN_NONE) == !rotary);
    static const int32_t fixed[][5] = {
        {0, 0, 0, 0, 0},
        {1000000000, -1000000000, 500000000, 90000000, -270000000},
        {INT32_MAX, INT32_MIN, INT32_MAX, INT32_MAX, INT32_MIN},
        {123456789, -98765432, 31415926, -45000000, 720000001},
    };
    for (size_t i = 0; i < sizeof fixed / sizeof fixed[0]; i++) {
        eval_at(&model, st3 == ABBE_OK ? &m3 : NULL, fixed[i], fixed[i] + 3);
    }
    const uint8_t *extra = data + total;
    for (size_t k = 0; k + 20u <= size - total && k < 20u * 8u; k += 20u) {
        int32_t v[5];
        for (unsigned j = 0; j < 5u; j++) {
            uint32_t u = ld_u32(extra + k + 4u * j);
            memcpy(&v[j], &u, sizeof u);
        }
        eval_at(&model, st3 == ABBE_OK ? &m3 : NULL, v, v + 3);
    }
    run_comp(&model);
}

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    fz_table_input(data, size, exercise);
    return 0;
}

/* libFuzzer harness: abbe_thermal_load() (format 1.3, the thermal block) on
 * arbitrary bytes, and for a table it accepts, the thermal runtime driven by
 * the bytes after the table (readings, valid masks, sample spacings, both
 * variants). Checks: a status in range and both outputs untouched on
 * failure; the loader agrees with abbe_model_load on tables without a block;
 * every output finite and within what the channel limits allow; the flags
 * only known bits (KNOWN_FLAGS). */
#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "abbe/abbe.h"
#include "fuzz_table_input.h"

#define CHECK(c)                                                               \
    do {                                                                       \
        if (!(c)) {                                                            \
            fprintf(stderr, "fuzz_thermal_load: check failed: %s (line %d)\n", #c, __LINE__); \
            abort();                                                           \
        }                                                                      \
    } while (0)

/* Every flag abbe/thermal.h defines, by name: a flag added there (as STUCK, 0x80, was
 * after this harness first spelled the mask 0x7F) is then known here too. */
#define KNOWN_FLAGS                                                                       \
    (ABBE_THERMAL_F_FAULTS | ABBE_THERMAL_F_LIMIT | ABBE_THERMAL_F_HOLD | ABBE_THERMAL_F_FADING)

static uint32_t ld32(const uint8_t *p)
{
    return (uint32_t)p[0] | (uint32_t)p[1] << 8 | (uint32_t)p[2] << 16 | (uint32_t)p[3] << 24;
}

/* The largest |output| the channel limits allow, um (tilts through |t_z|). */
static double bound_um(const abbe_thermal_model_t *th)
{
    double b = 0.0;
    for (unsigned c = 0; c < th->n_channels; c++) {
        double lim = (double)th->limit[c] * 1e-3;
        b += th->output[c] >= ABBE_THERMAL_OUT_A ? lim * fabs((double)th->tool_z_nm) * 1e-9 : lim;
    }
    return b + 1e-3;
}

static void run(const abbe_thermal_model_t *th, const uint8_t *extra, size_t n)
{
    abbe_thermal_state_t sf, sq;
    CHECK(abbe_thermal_init_f32(&sf, th, 0.5f) == ABBE_OK);
    CHECK(abbe_thermal_init_q(&sq, th, 500000u) == ABBE_OK);
    const double b = bound_um(th);
    for (size_t k = 0; k + 8u <= n && k < 8u * 64u; k += 8u) {
        /* per sample: 4 bytes valid mask, 2 bytes dt (ms), 2 bytes a base reading */
        uint32_t valid = ld32(extra + k);
        uint32_t dt_ms = 1u + ((uint32_t)extra[k + 4] | (uint32_t)extra[k + 5] << 8);
        int16_t base = (int16_t)((uint16_t)extra[k + 6] | (uint16_t)extra[k + 7] << 8);
        float xf[ABBE_THERMAL_MAX_INPUTS];
        int32_t xq[ABBE_THERMAL_MAX_INPUTS];
        for (unsigned i = 0; i < ABBE_THERMAL_MAX_INPUTS; i++) {
            int32_t v = (int32_t)base * 10 + (int32_t)i * 37;
            xq[i] = th->kind[i] == ABBE_THERMAL_SPEED ? v : v;
            xf[i] = th->kind[i] == ABBE_THERMAL_SPEED ? (float)v : (float)v * 1e-3f;
        }
        if ((valid & 0x80000000u) != 0u) {
            xf[valid & 15u] = NAN;
        }
        CHECK(abbe_thermal_update_f32(&sf, xf, valid, (float)dt_ms * 1e-3f) == ABBE_OK);
        CHECK(abbe_thermal_update_q(&sq, xq, valid, dt_ms) == ABBE_OK);
        for (unsigned r = 0; r < (extra[k] & 7u) + 1u; r++) {
            float ef[3] = {0.0f, 0.0f, 0.0f};
            int32_t eq[3] = {0, 0, 0};
            abbe_thermal_apply_f32(&sf, ef);
            abbe_thermal_apply_q(&sq, eq);
            for (unsigned a = 0; a < 3u; a++) {
                CHECK(isfinite(ef[a]) && fabs((double)ef[a]) <= b);
                CHECK(fabs((double)eq[a]) * 1e-3 <= b + 1e-3);
            }
        }
        CHECK((abbe_thermal_flags(&sf) & ~KNOWN_FLAGS) == 0u && (abbe_thermal_flags(&sq) & ~KNOWN_FLAGS) == 0u);
    }
}

static void exercise(const uint8_t *data, size_t size)
{
    abbe_model_t m, m_before, m3;
    abbe_thermal_model_t th, th_before;
    memset(&m, 0x5A, sizeof m);
    memset(&th, 0xA5, sizeof th);
    m_before = m;
    th_before = th;
    abbe_status_t st = abbe_thermal_load(&m, &th, data, size);
    CHECK(st <= ABBE_OK && st >= ABBE_STATUS_MIN);
    if (st != ABBE_OK) {
        CHECK(memcmp(&m, &m_before, sizeof m) == 0 && memcmp(&th, &th_before, sizeof th) == 0);
    }
    abbe_status_t st3 = abbe_model_load(&m3, data, size);
    if (size >= 8u && (data[6] | data[7] << 8) < 3) { /* no thermal block: the two loaders agree */
        CHECK(st == st3 || st3 == ABBE_E_VERSION_MINOR || st == ABBE_E_FLAGS);
    }
    if (st != ABBE_OK) {
        return;
    }
    const uint32_t total = abbe_model_size(&m);
    run(&th, data + total, size - total);
}

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    fz_table_input(data, size, exercise);
    return 0;
}

/* CMocka tests of the grblHAL plugin's core (include/abbe_grblhal_core.h),
 * built for both variants (test_grblhal_core_f32 / _q): segmentation, the
 * deviation bound it promises, forward / inverse, fade without jumps, and
 * table uploads that fail without touching the running table. Tables: the
 * golden 'backlash' (and 'paper') tables of tests/golden. */
#include <math.h>
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include <cmocka.h>

#include "abbe_grblhal_core.h"
#include "golden_data.h"
#include "golden_thermal.h"
#include "thermal_stuck.h"

static abbe_gh_t gh;

static const abbe_golden_table_t *golden(const char *name)
{
    for (uint32_t i = 0; i < abbe_golden_table_count; i++) {
        if (strcmp(abbe_golden_tables[i].name, name) == 0) {
            return &abbe_golden_tables[i];
        }
    }
    fail_msg("no golden table %s", name);
    return NULL;
}

static void start(const char *table)
{
    abbe_gh_params_t p;
    abbe_gh_default_params(&p);
    const abbe_golden_table_t *t = golden(table);
    assert_int_equal(abbe_gh_init(&gh, &p, t->blob, t->blob_size), ABBE_OK);
}

/* Travel box of the loaded table, mm. */
static void travel(float lo[3], float hi[3])
{
    for (unsigned j = 0; j < 3; j++) {
        abbe_axis_info_t info;
        assert_int_equal(abbe_model_axis_info(&gh.slot[0].model, j, &info), ABBE_OK);
        lo[j] = (float)info.travel_min_nm * 1e-6f;
        hi[j] = (float)info.travel_max_nm * 1e-6f;
    }
}

static uint32_t rng_state = 25u;
static float uniform(void)
{
    rng_state = rng_state * 1664525u + 1013904223u;
    return (float)(rng_state >> 8) / 16777216.0f;
}

static void error_um(const float p[3], float e[3])
{
    abbe_input_f32_t in = {{p[0], p[1], p[2]}, {0, 0, 0}, {20, 20, 20}};
    abbe_axis_info_t info;
    for (unsigned j = 0; j < 3; j++) {
        assert_int_equal(abbe_model_axis_info(&gh.slot[0].model, j, &info), ABBE_OK);
        in.temp_c[j] = (float)info.thermal_tref_mdegc * 1e-3f;
    }
    abbe_error_f32_t out;
    assert_int_equal(abbe_error_eval_f32(&gh.slot[0].model, &in, &out), ABBE_OK);
    memcpy(e, out.error_um, sizeof out.error_um);
}

/* The promise: along any segment of the chosen length the model leaves the
 * chord between its end values by at most the bound (checked on 300 random
 * segments in the travel, 65 points each). */
static void test_deviation_bound(void **state)
{
    (void)state;
    start("backlash");
    float lo[3], hi[3];
    travel(lo, hi);
    float len = gh.seg_len_mm, worst = 0.0f;
    assert_true(len > ABBE_GH_SEG_MIN_MM && len <= ABBE_GH_SEG_MAX_MM);
    for (int k = 0; k < 300; k++) {
        float a[3], d[3], n = 0.0f;
        for (unsigned j = 0; j < 3; j++) {
            a[j] = lo[j] + len + uniform() * (hi[j] - lo[j] - 2.0f * len);
            d[j] = uniform() - 0.5f;
            n += d[j] * d[j];
        }
        n = sqrtf(n);
        float b[3], ea[3], eb[3];
        for (unsigned j = 0; j < 3; j++) {
            b[j] = a[j] + d[j] / n * len;
        }
        error_um(a, ea);
        error_um(b, eb);
        for (int i = 1; i < 64; i++) {
            float t = (float)i / 64.0f, p[3], e[3];
            for (unsigned j = 0; j < 3; j++) {
                p[j] = a[j] + t * (b[j] - a[j]);
            }
            error_um(p, e);
            for (unsigned j = 0; j < 3; j++) {
                float dev = fabsf(e[j] - (ea[j] + t * (eb[j] - ea[j])));
                worst = dev > worst ? dev : worst;
            }
        }
    }
    print_message("segment %.3f mm, bound %.3f um, worst deviation seen %.3f um\n", (double)len,
                  (double)gh.params.max_dev_um, (double)worst);
    assert_true(worst <= gh.params.max_dev_um * 1.02f);
    /* a lower bound: shorter segments, quadratically (L = sqrt(8 dev / kappa),
     * within [ABBE_GH_SEG_MIN_MM, ABBE_GH_SEG_MAX_MM]) */
    float kappa = gh.slot[0].kappa_um_per_mm2;
    float full = sqrtf(8.0f * gh.params.max_dev_um / kappa);
    assert_float_equal(len, fminf(full, ABBE_GH_SEG_MAX_MM), len * 0.01f);
    abbe_gh_params_t p = gh.params;
    p.max_dev_um = 0.25f;
    assert_int_equal(abbe_gh_set_params(&gh, &p), ABBE_OK);
    assert_float_equal(gh.seg_len_mm, fminf(full * 0.5f, ABBE_GH_SEG_MAX_MM), len * 0.01f);
}

/* The curvature is the model's inside the travel: not the kink where the
 * library holds every term at its end value. kappa (a Gershgorin bound: at
 * least every directional second derivative) is compared with the largest
 * directional second difference found by this test at 20,000 random points
 * and directions inside the travel (half of them on its edges), h = 2 mm:
 * kappa >= 0.95 of it, and at most twice it (the stencil that reached 0.5 mm
 * outside the travel gave 29 times it on these tables). The _q build's
 * integer nm add rounding: up to 2 nm per second difference over h = 0.5 mm,
 * summed over a row of three, 0.024 um/mm^2. */
static void test_curvature_inside_travel(void **state)
{
    (void)state;
    static const char *const tables[] = {"backlash", "paper", "negative"};
    for (unsigned t = 0; t < sizeof tables / sizeof tables[0]; t++) {
        start(tables[t]);
        float lo[3], hi[3], h = 2.0f, seen = 0.0f;
        travel(lo, hi);
        for (int k = 0; k < 20000; k++) {
            float p[3], d[3], n = 0.0f;
            for (unsigned j = 0; j < 3; j++) {
                p[j] = lo[j] + h + uniform() * (hi[j] - lo[j] - 2.0f * h);
                if (k % 2) {
                    p[j] = uniform() < 0.5f ? lo[j] + h : hi[j] - h;
                }
                d[j] = uniform() - 0.5f;
                n += d[j] * d[j];
            }
            n = sqrtf(n);
            float a[3], b[3], e0[3], ea[3], eb[3];
            for (unsigned j = 0; j < 3; j++) {
                a[j] = p[j] + h * d[j] / n;
                b[j] = p[j] - h * d[j] / n;
            }
            error_um(p, e0);
            error_um(a, ea);
            error_um(b, eb);
            for (unsigned j = 0; j < 3; j++) {
                float s = fabsf(ea[j] - 2.0f * e0[j] + eb[j]) / (h * h);
                seen = s > seen ? s : seen;
            }
        }
        float kappa = gh.slot[0].kappa_um_per_mm2;
        float noise = ABBE_GH_FIXED_POINT ? 0.024f : 0.0f;
        print_message("%s: kappa %.4f um/mm^2, largest directional second difference seen %.4f\n", tables[t],
                      (double)kappa, (double)seen);
        assert_true(kappa >= 0.95f * seen);
        assert_true(kappa <= 2.0f * seen + noise);
    }
}

static void test_segments(void **state)
{
    (void)state;
    start("backlash");
    abbe_gh_line_t line;
    float a[3] = {10.0f, -10.0f, -10.0f}, b[3] = {110.0f, -60.0f, -30.0f}, p[3], prev[3];
    uint32_t n = abbe_gh_line_begin(&gh, &line, a, b);
    float len = sqrtf(100.0f * 100.0f + 50.0f * 50.0f + 20.0f * 20.0f);
    /* no direction yet: every axis "reverses" and the first segment ends at the take-up */
    assert_true(n >= (uint32_t)ceilf(len / gh.seg_len_mm));
    memcpy(prev, a, sizeof prev);
    uint32_t k = 0;
    while (abbe_gh_line_next(&line, p)) {
        float d = 0.0f;
        for (unsigned j = 0; j < 3; j++) {
            d += (p[j] - prev[j]) * (p[j] - prev[j]);
        }
        assert_true(sqrtf(d) <= gh.seg_len_mm * 1.0001f);
        memcpy(prev, p, sizeof prev);
        k++;
    }
    assert_int_equal(k, n);
    assert_memory_equal(prev, b, sizeof b); /* the last segment ends exactly at the target */
    /* short line: one segment */
    float c[3] = {10.1f, -10.0f, -10.0f};
    gh.last_dir[0] = 1;
    assert_int_equal(abbe_gh_line_begin(&gh, &line, a, c), 1u);
}

/* Lines that leave the table's travel: beyond it the library holds each term
 * at its end value, a kink the curvature does not bound. The line is split
 * where it crosses a face of the travel box, so every segment still keeps the
 * model within the bound of its chord (checked at 65 points on each segment of
 * 200 random lines from inside the travel to up to 60 mm beyond it, with a
 * bound of 0.05 um: segments of ~6 mm, where a chord across the kink would
 * leave the model by ~slope x L / 4). */
static void test_lines_leaving_the_travel(void **state)
{
    (void)state;
    start("backlash");
    abbe_gh_params_t prm = gh.params;
    prm.max_dev_um = 0.05f;
    assert_int_equal(abbe_gh_set_params(&gh, &prm), ABBE_OK);
    float lo[3], hi[3], worst = 0.0f;
    travel(lo, hi);
    uint32_t on_face = 0u;
    for (int k = 0; k < 200; k++) {
        float a[3], b[3];
        for (unsigned j = 0; j < 3; j++) {
            a[j] = lo[j] + 1.0f + uniform() * (hi[j] - lo[j] - 2.0f);
            b[j] = a[j] + (uniform() - 0.5f) * 60.0f;
        }
        unsigned out_axis = (unsigned)k % 3u;
        b[out_axis] = (k / 3) % 2 ? hi[out_axis] + 1.0f + 59.0f * uniform() : lo[out_axis] - 1.0f - 59.0f * uniform();
        for (unsigned j = 0; j < 3; j++) {
            gh.last_dir[j] = b[j] > a[j] ? 1 : -1; /* no take-up: only the faces split */
        }
        abbe_gh_line_t line;
        (void)abbe_gh_line_begin(&gh, &line, a, b);
        float prev[3], p[3], ea[3], eb[3];
        memcpy(prev, a, sizeof prev);
        while (abbe_gh_line_next(&line, p)) {
            for (unsigned j = 0; j < 3; j++) {
                on_face += fabsf(p[j] - lo[j]) < 1e-3f || fabsf(p[j] - hi[j]) < 1e-3f;
            }
            error_um(prev, ea);
            error_um(p, eb);
            for (int i = 1; i < 64; i++) {
                float t = (float)i / 64.0f, q[3], e[3];
                for (unsigned j = 0; j < 3; j++) {
                    q[j] = prev[j] + t * (p[j] - prev[j]);
                }
                error_um(q, e);
                for (unsigned j = 0; j < 3; j++) {
                    float dev = fabsf(e[j] - (ea[j] + t * (eb[j] - ea[j])));
                    worst = dev > worst ? dev : worst;
                }
            }
            memcpy(prev, p, sizeof prev);
        }
    }
    print_message("lines leaving the travel: segment %.3f mm, bound %.3f um, worst deviation %.4f um, "
                  "%u segment ends on a face\n", (double)gh.seg_len_mm, (double)prm.max_dev_um, (double)worst,
                  (unsigned)on_face);
    assert_true(on_face >= 200u); /* every line ends a segment where it leaves the travel */
    assert_true(worst <= prm.max_dev_um * 1.05f);
}

/* Forward then inverse gives the point back; switching never jumps. */
static void test_forward_inverse_fade(void **state)
{
    (void)state;
    start("backlash");
    assert_int_equal(abbe_gh_active(&gh), 0); /* disabled: lines pass through */
    assert_int_equal(abbe_gh_set_enabled(&gh, 1), ABBE_OK);
    assert_int_equal(abbe_gh_active(&gh), 1);
    float p[3] = {100.0f, -100.0f, -100.0f}, m[3], q[3];
    int32_t prev[3] = {0, 0, 0}, rate = (int32_t)(gh.params.rate_um_per_seg * 1000.0f) + 1;
    for (int k = 0; k < 80; k++) {
        p[0] += 1.5f;
        p[1] -= 0.7f;
        (void)abbe_gh_forward(&gh, p, m);
        for (unsigned j = 0; j < 3; j++) {
            assert_true(abs(gh.last_corr_nm[j] - prev[j]) <= rate);
            prev[j] = gh.last_corr_nm[j];
        }
        if (k < 30) {
            assert_int_equal(abbe_gh_state(&gh), ABBE_GH_FADING);
        }
    }
    assert_int_equal(abbe_gh_state(&gh), ABBE_GH_ON);
    assert_true(abbe_gh_inverse(&gh, m, q) <= 4);
    for (unsigned j = 0; j < 3; j++) {
        assert_float_equal(q[j], p[j], 2e-5f);
        assert_true(fabsf(m[j] - p[j]) > 0.0f || gh.last_corr_nm[j] == 0);
    }
    /* a motor position near the last one: the inverse follows the model */
    float m2[3] = {m[0] + 0.5f, m[1], m[2]}, q2[3];
    (void)abbe_gh_inverse(&gh, m2, q2);
    (void)abbe_gh_forward(&gh, q2, m);
    for (unsigned j = 0; j < 3; j++) {
        assert_float_equal(m[j], m2[j], 2e-4f); /* fresh step: only the direction state moves */
    }
    assert_int_equal(abbe_gh_set_enabled(&gh, 0), ABBE_OK);
    for (int k = 0; k < 80; k++) {
        p[0] -= 1.5f;
        (void)abbe_gh_forward(&gh, p, m);
        for (unsigned j = 0; j < 3; j++) {
            assert_true(abs(gh.last_corr_nm[j] - prev[j]) <= rate);
            prev[j] = gh.last_corr_nm[j];
        }
    }
    assert_int_equal(abbe_gh_state(&gh), ABBE_GH_OFF);
    assert_int_equal(abbe_gh_active(&gh), 0);
    assert_memory_equal(m, p, sizeof p);
}

static abbe_status_t upload(const uint8_t *blob, uint32_t size, uint32_t crc, int skip_last, int swap)
{
    const char *why;
    abbe_status_t st = abbe_gh_upload_begin(&gh, size, crc, &why);
    if (st != ABBE_OK) {
        return st;
    }
    uint32_t offs[64], n = 0;
    for (uint32_t o = 0; o < size; o += 96u) {
        offs[n++] = o;
    }
    if (swap) {
        uint32_t t = offs[1];
        offs[1] = offs[2];
        offs[2] = t;
    }
    for (uint32_t i = 0; i < n - (skip_last ? 1u : 0u); i++) {
        uint32_t len = size - offs[i] < 96u ? size - offs[i] : 96u;
        st = abbe_gh_upload_data(&gh, offs[i], blob + offs[i], len, &why);
        if (st != ABBE_OK) {
            return st;
        }
    }
    st = abbe_gh_upload_commit(&gh, &why);
    print_message("upload: %s\n", st == ABBE_OK ? "accepted" : why);
    return st;
}

static void test_upload(void **state)
{
    (void)state;
    start("backlash");
    assert_int_equal(abbe_gh_set_enabled(&gh, 1), ABBE_OK);
    float p[3] = {50.0f, -50.0f, -50.0f}, m[3];
    (void)abbe_gh_forward(&gh, p, m);
    uint32_t crc0 = abbe_model_crc(abbe_gh_model(&gh));
    const abbe_golden_table_t *t = golden("paper");
    uint8_t bad[ABBE_GH_TABLE_MAX_BYTES];
    memcpy(bad, t->blob, t->blob_size);
    bad[200] ^= 0x40u;
    uint32_t crc = abbe_crc32(0u, t->blob, t->blob_size);
    assert_int_not_equal(upload(t->blob, t->blob_size, crc ^ 1u, 0, 0), ABBE_OK);
    assert_int_not_equal(upload(bad, t->blob_size, abbe_crc32(0u, bad, t->blob_size), 0, 0), ABBE_OK);
    assert_int_not_equal(upload(t->blob, t->blob_size, crc, 1, 0), ABBE_OK);
    assert_int_not_equal(upload(t->blob, t->blob_size, crc, 0, 1), ABBE_OK);
    const char *why;
    assert_int_not_equal(abbe_gh_upload_begin(&gh, ABBE_GH_TABLE_MAX_BYTES + 4u, crc, &why), ABBE_OK);
    /* the refusal a user reads: the size and the limit in bytes, no macro name */
    char want[96];
    snprintf(want, sizeof want, "table of %u bytes: this build takes 16 to %u bytes",
             (unsigned)(ABBE_GH_TABLE_MAX_BYTES + 4u), (unsigned)ABBE_GH_TABLE_MAX_BYTES);
    assert_string_equal(why, want);
    assert_int_not_equal(abbe_gh_upload_begin(&gh, 15u, crc, &why), ABBE_OK);
    assert_string_equal(why, "table of 15 bytes: this build takes 16 to 8192 bytes");
    p[0] += 1.0f;
    (void)abbe_gh_forward(&gh, p, m);
    assert_int_equal(abbe_model_crc(abbe_gh_model(&gh)), crc0); /* the running table stays */
    assert_int_equal(upload(t->blob, t->blob_size, crc, 0, 0), ABBE_OK);
    assert_int_equal(abbe_model_crc(abbe_gh_model(&gh)), crc0); /* not before the next segment */
    assert_int_not_equal(abbe_gh_upload_begin(&gh, t->blob_size, crc, &why), ABBE_OK); /* one at a time */
    p[0] += 1.0f;
    uint32_t flags = abbe_gh_forward(&gh, p, m);
    assert_true(flags & ABBE_FLAG_MODEL_SWAPPED);
    abbe_model_t paper;
    assert_int_equal(abbe_model_load(&paper, t->blob, t->blob_size), ABBE_OK);
    assert_int_equal(abbe_model_crc(abbe_gh_model(&gh)), abbe_model_crc(&paper));
    /* the next upload goes into the other slot: the running blob is never overwritten */
    assert_int_equal(upload(golden("backlash")->blob, golden("backlash")->blob_size,
                            abbe_crc32(0u, golden("backlash")->blob, golden("backlash")->blob_size), 0, 0),
                     ABBE_OK);
    assert_int_equal(abbe_model_crc(abbe_gh_model(&gh)), abbe_model_crc(&paper));
}

/* A correction beyond the limit latches a fault: the plugin reports FAULT and
 * the correction fades out at the rate limit, never a jump; reset clears it. */
static void test_fault_fades_out(void **state)
{
    (void)state;
    start("backlash");
    assert_int_equal(abbe_gh_set_enabled(&gh, 1), ABBE_OK);
    float p[3] = {100.0f, -100.0f, -100.0f}, m[3];
    for (int k = 0; k < 40; k++) {
        p[0] += 1.0f;
        (void)abbe_gh_forward(&gh, p, m);
    }
    assert_int_equal(abbe_gh_state(&gh), ABBE_GH_ON);
    int32_t prev[3] = {gh.last_corr_nm[0], gh.last_corr_nm[1], gh.last_corr_nm[2]};
    abbe_gh_params_t prm = gh.params;
    prm.limit_um = 1.0f; /* below this table's correction */
    assert_int_equal(abbe_gh_set_params(&gh, &prm), ABBE_OK);
    int32_t rate = (int32_t)(prm.rate_um_per_seg * 1000.0f) + 1;
    int faulted = 0;
    for (int k = 0; k < 80; k++) {
        p[0] += 1.0f;
        uint32_t flags = abbe_gh_forward(&gh, p, m);
        faulted |= (flags & ABBE_FLAG_LIMIT) != 0u;
        for (unsigned j = 0; j < 3; j++) {
            assert_true(abs(gh.last_corr_nm[j] - prev[j]) <= rate);
            prev[j] = gh.last_corr_nm[j];
        }
    }
    assert_true(faulted);
    assert_int_equal(abbe_gh_state(&gh), ABBE_GH_FAULT);
    for (unsigned j = 0; j < 3; j++) {
        assert_int_equal(gh.last_corr_nm[j], 0);
    }
    prm.limit_um = 200.0f;
    assert_int_equal(abbe_gh_set_params(&gh, &prm), ABBE_OK);
    assert_int_equal(abbe_gh_set_enabled(&gh, 2), ABBE_OK); /* $ABBERESET */
    assert_int_equal(abbe_gh_set_enabled(&gh, 1), ABBE_OK);
    for (int k = 0; k < 40; k++) {
        p[0] += 1.0f;
        (void)abbe_gh_forward(&gh, p, m);
    }
    assert_int_equal(abbe_gh_state(&gh), ABBE_GH_ON);
}

/* The stored-table header: a round trip, and every way a header read back
 * from storage can be wrong (erased, invalidated, foreign, corrupted, a size
 * the storage or the plugin cannot hold). */
static void test_store_header(void **state)
{
    (void)state;
    uint8_t h[ABBE_GH_STORE_HEADER_BYTES], bad[ABBE_GH_STORE_HEADER_BYTES];
    uint32_t size = 0, crc = 0;
    const char *why;
    abbe_gh_store_header(h, 1412u, 0x64BE1F61u);
    assert_int_equal(abbe_gh_store_parse(h, 2032u, &size, &crc, &why), ABBE_GH_STORE_VALID);
    assert_int_equal(size, 1412u);
    assert_int_equal(crc, 0x64BE1F61u);
    assert_int_equal(h[0], 'A'); /* little-endian magic "ABT1" */
    assert_int_equal(h[3], '1');
    assert_int_equal(abbe_gh_store_parse(h, 1411u, &size, &crc, &why), ABBE_GH_STORE_CORRUPT);
    assert_non_null(strstr(why, "size"));
    memset(bad, 0xFF, sizeof bad);
    assert_int_equal(abbe_gh_store_parse(bad, 2032u, &size, &crc, &why), ABBE_GH_STORE_NONE);
    memset(bad, 0, sizeof bad);
    assert_int_equal(abbe_gh_store_parse(bad, 2032u, &size, &crc, &why), ABBE_GH_STORE_NONE);
    for (unsigned k = 0; k < sizeof h; k++) { /* any single flipped bit is caught */
        memcpy(bad, h, sizeof h);
        bad[k] ^= 0x10u;
        assert_int_equal(abbe_gh_store_parse(bad, 2032u, &size, &crc, &why), ABBE_GH_STORE_CORRUPT);
        assert_true(why[0] != '\0');
    }
    abbe_gh_store_header(h, ABBE_GH_TABLE_MAX_BYTES + 4u, 1u);
    assert_int_equal(abbe_gh_store_parse(h, 0xFFFFFFFFu, &size, &crc, &why), ABBE_GH_STORE_CORRUPT);
    abbe_gh_store_header(h, 8u, 1u);
    assert_int_equal(abbe_gh_store_parse(h, 2032u, &size, &crc, &why), ABBE_GH_STORE_CORRUPT);
}

/* A table read into slot 0's RAM is validated in place; a corrupted one is
 * refused and the caller starts again with another (or none). */
static void test_boot_in_place(void **state)
{
    (void)state;
    abbe_gh_params_t p;
    abbe_gh_default_params(&p);
    const abbe_golden_table_t *t = golden("paper");
    abbe_model_t paper;
    assert_int_equal(abbe_model_load(&paper, t->blob, t->blob_size), ABBE_OK);
    start("backlash"); /* whatever ran before */
    memcpy(abbe_gh_boot_buffer(&gh), t->blob, t->blob_size);
    assert_int_equal(abbe_gh_init(&gh, &p, abbe_gh_boot_buffer(&gh), t->blob_size), ABBE_OK);
    assert_int_equal(abbe_model_crc(abbe_gh_model(&gh)), abbe_model_crc(&paper));
    assert_int_equal(gh.running, 0);
    assert_true(gh.seg_len_mm > 0.0f && gh.seg_len_mm <= ABBE_GH_SEG_MAX_MM);
    abbe_gh_boot_buffer(&gh)[200] ^= 0x40u;
    assert_int_not_equal(abbe_gh_init(&gh, &p, abbe_gh_boot_buffer(&gh), t->blob_size), ABBE_OK);
    assert_null(abbe_gh_model(&gh));
    assert_int_equal(gh.running, 0xFF);
}

/* Homing: the correction restarts from zero where the motors stand (the
 * inverse is the identity there), then fades in without a jump. */
static void test_rehome(void **state)
{
    (void)state;
    start("backlash");
    assert_int_equal(abbe_gh_set_enabled(&gh, 1), ABBE_OK);
    float p[3] = {100.0f, -100.0f, -100.0f}, m[3], q[3];
    for (int k = 0; k < 40; k++) {
        p[0] += 1.0f;
        (void)abbe_gh_forward(&gh, p, m);
    }
    assert_int_equal(abbe_gh_state(&gh), ABBE_GH_ON);
    assert_true(gh.last_corr_nm[0] != 0 || gh.last_corr_nm[1] != 0 || gh.last_corr_nm[2] != 0);
    assert_int_equal(abbe_gh_rehome(&gh), ABBE_OK);
    float home[3] = {0.0f, 0.0f, 0.0f};
    abbe_gh_set_position(&gh, home);
    (void)abbe_gh_inverse(&gh, home, q);
    assert_memory_equal(q, home, sizeof home); /* MPos = grblHAL's own at home */
    assert_int_equal(abbe_gh_state(&gh), ABBE_GH_FADING);
    int32_t prev[3] = {0, 0, 0}, rate = (int32_t)(gh.params.rate_um_per_seg * 1000.0f) + 1;
    memcpy(p, home, sizeof p);
    for (int k = 0; k < 60; k++) {
        p[0] += 1.0f;
        p[1] -= 1.0f;
        p[2] -= 1.0f;
        (void)abbe_gh_forward(&gh, p, m);
        for (unsigned j = 0; j < 3; j++) {
            assert_true(abs(gh.last_corr_nm[j] - prev[j]) <= rate);
            prev[j] = gh.last_corr_nm[j];
        }
    }
    assert_int_equal(abbe_gh_state(&gh), ABBE_GH_ON);
}

/* The thermal block (format 1.3): samples at the clock's times, the thermal
 * tip error (the Python reference's golden values) added at every segment end
 * once faded in; a sensor fault (open input, out of range) and missing
 * samples fade it out by elapsed time, one segment moving it by no more than
 * |tip| x elapsed / fade_s; a table without a block refuses samples. */
static abbe_gh_t ref_gh; /* the same table, never sampled: the geometric correction alone */

static int32_t th_abs(int32_t v)
{
    return v < 0 ? -v : v;
}

/* Per axis: the sum of |tip error| of the channels that move it, nm (a fade
 * moves each channel's part by elapsed / fade_s; they may cancel in the sum). */
static void tip_parts(const abbe_thermal_state_t *st, int32_t parts[3])
{
    parts[0] = parts[1] = parts[2] = 0;
    for (unsigned c = 0; c < abbe_thermal_n_channels(st->model); c++) {
        int32_t v = ABBE_GH_FIXED_POINT ? st->tipq[c] : (int32_t)(st->tip[c] * 1000.0f);
        parts[st->tip_axis[c]] += th_abs(v);
    }
}

static void test_thermal(void **state)
{
    (void)state;
    const abbe_golden_thermal_sample_t *S = abbe_golden_thermal_samples;
    abbe_gh_params_t prm;
    abbe_gh_default_params(&prm);
    prm.rate_um_per_seg = 1000.0f; /* the thermal fade, not the rate limit, is under test */
    assert_int_equal(abbe_gh_init(&gh, &prm, abbe_golden_thermal_blob, abbe_golden_thermal_blob_size), ABBE_OK);
    assert_int_equal(abbe_gh_init(&ref_gh, &prm, abbe_golden_thermal_blob, abbe_golden_thermal_blob_size), ABBE_OK);
    assert_non_null(abbe_gh_thermal(&gh));
    assert_int_equal(abbe_gh_set_enabled(&gh, 1), ABBE_OK);
    assert_int_equal(abbe_gh_set_enabled(&ref_gh, 1), ABBE_OK);
    float lo[3], hi[3], p[3], m[3];
    travel(lo, hi);
    for (unsigned j = 0; j < 3; j++) {
        p[j] = 0.5f * (lo[j] + hi[j]);
    }
    const char *why = "";
    uint32_t t = 0u, seg_t = 0u;
    int after_sample = 0; /* the first segment end after a sample also takes the sample's lag increment */
    int32_t prev_d[3] = {0, 0, 0}, tip_max[3] = {0, 0, 0};
    int32_t step_max_fault[3] = {0, 0, 0};
    int saw_open = 0, saw_range = 0, saw_gap = 0;
    const uint32_t n_samples = 120u;
    for (uint32_t n = 0; n < n_samples; n++) {
        /* samples 40..47: the speed input open; 60..63: temperature 3 at 500 degC;
         * 80..91 never arrive (180 s: more than max_gap = 120 s) */
        int missing = n >= 80u && n < 92u;
        t += n ? S[n].dt_ms : 0u;
        /* segment ends every 1000 ms up to this sample's time, two at the same ms */
        while (seg_t + 1000u <= t) {
            seg_t += 1000u;
            int32_t parts[3];
            tip_parts(abbe_gh_thermal(&gh), parts);
            for (int twice = 0; twice < 2; twice++) {
                abbe_gh_clock(&gh, seg_t);
                (void)abbe_gh_forward(&gh, p, m);
                (void)abbe_gh_forward(&ref_gh, p, m);
                int32_t d[3];
                for (unsigned j = 0; j < 3; j++) {
                    d[j] = gh.last_corr_nm[j] - ref_gh.last_corr_nm[j];
                    if (twice && n >= 5u) { /* 0 ms elapsed (the compensator faded in): nothing moves */
                        assert_int_equal(d[j], prev_d[j]);
                    }
                    /* between samples only the fade moves it, by elapsed / fade_s of the tip */
                    int32_t step = th_abs(d[j] - prev_d[j]);
                    if (n >= 40u && !after_sample) {
                        if (step > step_max_fault[j]) {
                            step_max_fault[j] = step;
                        }
                        assert_true(step <= parts[j] * 1000 / 30000 + 3);
                    }
                    prev_d[j] = d[j];
                }
            }
            after_sample = 0;
        }
        abbe_gh_clock(&gh, t);
        if (!missing) {
            after_sample = 1;
            float x[ABBE_GOLDEN_THERMAL_INPUTS];
            memcpy(x, S[n].x, sizeof x);
            uint32_t mask = (n >= 40u && n < 48u) ? 0x0FFFFu : 0x1FFFFu;
            if (n >= 60u && n < 64u) {
                x[3] = 500.0f;
            }
            assert_int_equal(abbe_gh_thermal_sample(&gh, x, mask, &why), ABBE_OK);
            assert_int_equal(abbe_gh_thermal_sample(&gh, x, mask, &why), ABBE_E_ARG); /* same ms */
            uint32_t fl = abbe_thermal_flags(abbe_gh_thermal(&gh));
            saw_open |= (fl & ABBE_THERMAL_F_OPEN) != 0u;
            saw_range |= (fl & ABBE_THERMAL_F_RANGE) != 0u;
            if (n == 40u) {
                assert_true(fl & ABBE_THERMAL_F_HOLD);
            }
        }
        saw_gap |= (abbe_thermal_events(abbe_gh_thermal(&gh)) & ABBE_THERMAL_F_GAP) != 0u;
        /* faded in (30 s) and steady: the thermal part is the reference's tip error */
        if ((n >= 10u && n < 40u) || n == 59u || n == 79u || n == 119u) {
            for (unsigned j = 0; j < 3; j++) {
                int32_t tip = ABBE_GH_FIXED_POINT ? S[n - 1u].tip_q_nm[j] : S[n - 1u].tip_f32_nm[j];
                if (n < 40u && th_abs(tip) > tip_max[j]) {
                    tip_max[j] = th_abs(tip);
                }
                /* correction = -(error): the difference is minus the tip error (sample n - 1 is the newest here) */
                /* after the faults the held time was caught up in one backward Euler step: close, not equal */
                int32_t tol = n < 40u ? 30 + th_abs(tip) / 2000 : 30 + th_abs(tip) / 100;
                if (n >= 40u) {
                    print_message("sample %u axis %u: thermal part %d nm, reference tip %d nm\n", n - 1u, j,
                                  -prev_d[j], tip);
                }
                assert_true(th_abs(prev_d[j] + tip) <= tol);
            }
        }
        if (n == 47u || n == 91u) { /* 30 s after the fault / more than 120 s without samples: faded out */
            for (unsigned j = 0; j < 3; j++) {
                assert_int_equal(prev_d[j], 0);
            }
        }
    }
    assert_true(saw_open);
    assert_true(saw_range);
    assert_true(saw_gap);
    for (unsigned j = 0; j < 3; j++) {
        print_message("axis %u: thermal tip up to %d nm; largest change per 1 s segment through the faults %d nm\n",
                      j, tip_max[j], step_max_fault[j]);
        assert_true(tip_max[j] > 0);
    }
    /* a table without a thermal block: no state, samples refused */
    start("backlash");
    assert_null(abbe_gh_thermal(&gh));
    float x[ABBE_GOLDEN_THERMAL_INPUTS] = {0};
    assert_int_equal(abbe_gh_thermal_sample(&gh, x, 0x1FFFFu, &why), ABBE_E_ARG);
    assert_true(strlen(why) > 0u);
}

/* A stuck sensor: the golden table with input ABBE_STUCK_INPUT's stuck check
 * on (2 min, 0.02 K), a sample every 1 s of the clock, two segment ends per
 * second (250 and 750 ms after the sample); the input ramps, then repeats one
 * value for 180 s, then ramps again. The flags ($ABBE's THERMAL FLAGS field
 * prints abbe_thermal_flags of this state) show ABBE_THERMAL_F_STUCK with HOLD
 * and the input in FAULTS exactly 120 s after the last change; the thermal
 * part fades out by elapsed time (no segment end moves it by more than
 * |tip| x elapsed / fade_s between samples), and everything clears when the
 * reading moves again. */
#define STUCK_HOLD_FROM 40u  /* samples (1 s apart) */
#define STUCK_HOLD_TO 220u
#define STUCK_SAMPLES 270u

static void test_thermal_stuck(void **state)
{
    (void)state;
    static union { uint32_t align; uint8_t b[8192]; } blob;
    size_t size = abbe_stuck_blob(blob.b, sizeof blob.b);
    assert_true(size > 0u);
    abbe_gh_params_t prm;
    abbe_gh_default_params(&prm);
    prm.rate_um_per_seg = 1000.0f; /* the thermal fade, not the rate limit, is under test */
    assert_int_equal(abbe_gh_init(&gh, &prm, blob.b, size), ABBE_OK);
    assert_int_equal(abbe_gh_init(&ref_gh, &prm, blob.b, size), ABBE_OK);
    assert_int_equal(abbe_gh_set_enabled(&gh, 1), ABBE_OK);
    assert_int_equal(abbe_gh_set_enabled(&ref_gh, 1), ABBE_OK);
    const abbe_thermal_state_t *st = abbe_gh_thermal(&gh);
    assert_non_null(st);
    uint32_t reads = 0; /* channels that read the stuck input */
    for (unsigned c = 0; c < abbe_thermal_n_channels(st->model); c++) {
        reads |= ((st->model->channel_inputs[c] >> ABBE_STUCK_INPUT) & 1u) << c;
    }
    assert_true(reads != 0u);
    float lo[3], hi[3], p[3], m[3];
    travel(lo, hi);
    for (unsigned j = 0; j < 3; j++) {
        p[j] = 0.5f * (lo[j] + hi[j]);
    }
    const int32_t base = abbe_golden_thermal_samples[0].x_milli[ABBE_STUCK_INPUT];
    const char *why = "";
    int32_t prev_d[3] = {0, 0, 0}, step_between = 0, step_fade = 0, step_clean = 0;
    uint32_t i_flag = 0, i_clear = 0;
    for (uint32_t i = 0; i < STUCK_SAMPLES; i++) {
        const abbe_golden_thermal_sample_t *s =
            &abbe_golden_thermal_samples[i < abbe_golden_thermal_sample_count ? i : abbe_golden_thermal_sample_count - 1u];
        float x[ABBE_GOLDEN_THERMAL_INPUTS];
        memcpy(x, s->x, sizeof x);
        x[ABBE_STUCK_INPUT] = (float)abbe_stuck_reading_milli(base, i, STUCK_HOLD_FROM, STUCK_HOLD_TO) * 1e-3f;
        abbe_gh_clock(&gh, 1000u * i);
        assert_int_equal(abbe_gh_thermal_sample(&gh, x, 0x1FFFFu, &why), ABBE_OK);
        uint32_t fl = abbe_thermal_flags(st);
        if ((fl & ABBE_THERMAL_F_STUCK) && i_flag == 0u) {
            i_flag = i;
        }
        if (i_flag != 0u && i_clear == 0u) {
            if (!(fl & ABBE_THERMAL_F_STUCK)) {
                i_clear = i;
            } else {
                assert_true(fl & ABBE_THERMAL_F_HOLD);
                assert_int_equal(abbe_thermal_input_faults(st), 1u << ABBE_STUCK_INPUT);
            }
        }
        if (i >= 31u && i_flag == 0u) { /* faded in (the table's 30 s), not yet stuck */
            assert_int_equal(fl & (ABBE_THERMAL_F_FAULTS | ABBE_THERMAL_F_HOLD | ABBE_THERMAL_F_FADING), 0u);
        }
        for (uint32_t half = 0; half < 2u; half++) {
            int32_t parts[3];
            tip_parts(st, parts);
            abbe_gh_clock(&gh, 1000u * i + 250u + 500u * half);
            (void)abbe_gh_forward(&gh, p, m);
            (void)abbe_gh_forward(&ref_gh, p, m);
            for (unsigned j = 0; j < 3; j++) {
                int32_t d = gh.last_corr_nm[j] - ref_gh.last_corr_nm[j];
                int32_t step = th_abs(d - prev_d[j]);
                prev_d[j] = d;
                if (i >= 5u && i < STUCK_HOLD_FROM) {
                    step_clean = step > step_clean ? step : step_clean;
                }
                if (i_flag != 0u) {
                    step_fade = step > step_fade ? step : step_fade;
                    if (half) { /* 500 ms after the previous segment end, no sample between: the fades alone */
                        step_between = step > step_between ? step : step_between;
                        assert_true(step <= parts[j] * 500 / 30000 + 3);
                    }
                }
            }
        }
        if (i_flag != 0u && i == i_flag + 31u) { /* the table's fade (30 s) is over: faded out */
            for (unsigned c = 0; c < abbe_thermal_n_channels(st->model); c++) {
                int out = ABBE_GH_FIXED_POINT ? st->wq24[c] == 0u : st->w[c] == 0.0f;
                assert_int_equal(out, (reads >> c) & 1u);
            }
        }
    }
    assert_true(i_flag != 0u);
    assert_int_equal(i_clear, STUCK_HOLD_TO); /* the first sample that moves */
    assert_int_equal(abbe_thermal_flags(st) & (ABBE_THERMAL_F_FAULTS | ABBE_THERMAL_F_HOLD | ABBE_THERMAL_F_FADING), 0u);
    assert_true(abbe_thermal_events(st) & ABBE_THERMAL_F_STUCK);
    uint32_t flag_ms = (i_flag - (STUCK_HOLD_FROM - 1u)) * 1000u;
    print_message("grblHAL stuck sensor (%s): FLAGS 80 %u ms after the last change; largest thermal change per "
                  "segment end %d nm clean, %d nm from the flag through the fade-out and back, %d nm between "
                  "samples (500 ms)\n", ABBE_GH_FIXED_POINT ? "q" : "f32", flag_ms, step_clean, step_fade,
                  step_between);
    assert_int_equal(flag_ms, 60000u * ABBE_STUCK_MIN);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_deviation_bound),
        cmocka_unit_test(test_curvature_inside_travel),
        cmocka_unit_test(test_segments),
        cmocka_unit_test(test_lines_leaving_the_travel),
        cmocka_unit_test(test_forward_inverse_fade),
        cmocka_unit_test(test_upload),
        cmocka_unit_test(test_fault_fades_out),
        cmocka_unit_test(test_store_header),
        cmocka_unit_test(test_boot_in_place),
        cmocka_unit_test(test_rehome),
        cmocka_unit_test(test_thermal),
        cmocka_unit_test(test_thermal_stuck),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}

/* Five-axis tables (format 1.2): loader, evaluation against the Python
 * reference's golden vectors (tests/golden/golden_five.*), a full turn as an
 * exact period, 3-axis tables under the five-axis API, and the compensator's
 * five-axis step with the same safety as the 3-axis one. */
#include <math.h>
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include <cmocka.h>

#include "abbe/abbe.h"
#include "blob_builder.h"
#include "golden_data.h"
#include "golden_five.h"

static int64_t diff_pm_f32(float um, int32_t expect_pm)
{
    double d = (double)um * 1.0e6 - (double)expect_pm;
    return (int64_t)(d < 0 ? -d : d);
}

static int64_t diff_q(int32_t value, int32_t expect_pico)
{
    int64_t d = (int64_t)value * 1000 - expect_pico; /* nm -> pm, nrad -> prad */
    return d < 0 ? -d : d;
}

/* Loads golden table t; 0 when this library does not read its kind (built with
 * ABBE_NO_FIVE_KINDS: format 1.4's kinds 3-5 are refused by their minor). */
static int load_five(unsigned t, abbe_five_model_t *m)
{
    const abbe_golden_five_table_t *g = &abbe_golden_five_tables[t];
#if defined(ABBE_NO_FIVE_KINDS)
    if (g->kind >= ABBE_KIN_XYZBC_HH) {
        assert_int_equal(abbe_five_model_load(m, g->blob, g->blob_size), ABBE_E_VERSION_MINOR);
        return 0;
    }
#endif
    if (ABBE_FIVE_KIND_BUILT(g->kind) == 0u) { /* a library built for other kinds (ABBE_FIVE_KINDS) */
        assert_int_equal(abbe_five_model_load(m, g->blob, g->blob_size), ABBE_E_KIND);
        return 0;
    }
    assert_int_equal(abbe_five_model_load(m, g->blob, g->blob_size), ABBE_OK);
    assert_int_equal(abbe_five_model_kind(m), g->kind);
    return 1;
}

/* The tests below that use the trunnion golden tables ac_full (kind 1) and bc_motions
 * (kind 2) are skipped in a library built without them (ABBE_FIVE_KINDS). */
#define NEEDS_TRUNNIONS()                                                                                   \
    do {                                                                                                    \
        if (ABBE_FIVE_KIND_BUILT(ABBE_KIN_XYZAC_TRT) == 0u || ABBE_FIVE_KIND_BUILT(ABBE_KIN_XYZBC_TRT) == 0u) { \
            skip();                                                                                         \
        }                                                                                                   \
    } while (0)

/* A table of a kind the library was built without is refused with ABBE_E_KIND, *model
 * untouched, whatever else the table holds; every built kind loads. Meaningful in a library
 * built for some kinds (test_five_axis_kind3: -DABBE_FIVE_KINDS=3); with every kind built
 * it checks that each golden table loads. */
static void test_kinds_built(void **state)
{
    (void)state;
    unsigned refused = 0, loaded = 0;
    for (unsigned t = 0; t < abbe_golden_five_table_count; t++) {
        const abbe_golden_five_table_t *g = &abbe_golden_five_tables[t];
        abbe_five_model_t m;
        memset(&m, 0xA5, sizeof m);
        abbe_five_model_t before = m;
        const abbe_status_t st = abbe_five_model_load(&m, g->blob, g->blob_size);
#if defined(ABBE_NO_FIVE_KINDS)
        if (g->kind >= ABBE_KIN_XYZBC_HH) {
            assert_int_equal(st, ABBE_E_VERSION_MINOR);
            continue;
        }
#endif
        if (ABBE_FIVE_KIND_BUILT(g->kind) == 0u) {
            assert_int_equal(st, ABBE_E_KIND);
            assert_memory_equal(&m, &before, sizeof m);
            assert_string_equal(abbe_strerror(st), "five-axis kind not built into this library");
            refused++;
        } else {
            assert_int_equal(st, ABBE_OK);
            assert_int_equal(abbe_five_model_kind(&m), g->kind);
            loaded++;
        }
    }
    assert_true(loaded > 0u);
    printf("five-axis kinds built 0x%02x: %u golden tables loaded, %u refused (ABBE_E_KIND)\n",
           (unsigned)ABBE_FIVE_KIND_MASK, loaded, refused);
}

static void test_golden_f32(void **state)
{
    (void)state;
    int64_t worst_pos = 0, worst_rot = 0;
    for (unsigned t = 0; t < abbe_golden_five_table_count; t++) {
        abbe_five_model_t m;
        if (!load_five(t, &m)) {
            continue;
        }
        const abbe_golden_five_table_t *g = &abbe_golden_five_tables[t];
        const int64_t before_pos = worst_pos, before_rot = worst_rot;
        worst_pos = worst_rot = 0; /* per table, printed below, then the overall worst */
        for (uint32_t i = g->first_point; i < g->first_point + g->n_points; i++) {
            const abbe_golden_five_point_t *p = &abbe_golden_five_points[i];
            abbe_five_input_f32_t in;
            memset(&in, 0, sizeof in);
            memcpy(in.pos_mm, p->pos_mm, sizeof in.pos_mm);
            memcpy(in.angle_deg, p->angle_deg, sizeof in.angle_deg);
            abbe_five_error_f32_t out;
            assert_int_equal(abbe_five_error_eval_f32(&m, &in, &out), ABBE_OK);
            for (int k = 0; k < 3; k++) {
                int64_t dp = diff_pm_f32(out.error_um[k], p->expect_f32_pm[k]);
                int64_t dr = diff_pm_f32(out.orient_urad[k], p->expect_f32_prad[k]);
                worst_pos = dp > worst_pos ? dp : worst_pos;
                worst_rot = dr > worst_rot ? dr : worst_rot;
                if (dp > ABBE_GOLDEN_FIVE_TOL_PM || dr > ABBE_GOLDEN_FIVE_TOL_PRAD) {
                    fail_msg("%s point %u comp %d: position %.6f um vs %d pm, orientation %.6f urad vs %d prad",
                             g->name, (unsigned)i, k, (double)out.error_um[k], p->expect_f32_pm[k],
                             (double)out.orient_urad[k], p->expect_f32_prad[k]);
                }
            }
        }
        printf("five-axis f32 %s (kind %u): worst |C - reference| position %lld pm, orientation %lld prad\n", g->name,
               (unsigned)g->kind, (long long)worst_pos, (long long)worst_rot);
        worst_pos = worst_pos > before_pos ? worst_pos : before_pos;
        worst_rot = worst_rot > before_rot ? worst_rot : before_rot;
    }
    printf("five-axis f32: worst |C - reference| position %lld pm, orientation %lld prad\n", (long long)worst_pos,
           (long long)worst_rot);
}

static void test_golden_q(void **state)
{
    (void)state;
    int64_t worst_pos = 0, worst_rot = 0;
    for (unsigned t = 0; t < abbe_golden_five_table_count; t++) {
        abbe_five_model_t m;
        if (!load_five(t, &m)) {
            continue;
        }
        const abbe_golden_five_table_t *g = &abbe_golden_five_tables[t];
        const int64_t before_pos = worst_pos, before_rot = worst_rot;
        worst_pos = worst_rot = 0; /* per table, printed below, then the overall worst */
        for (uint32_t i = g->first_point; i < g->first_point + g->n_points; i++) {
            const abbe_golden_five_point_t *p = &abbe_golden_five_points[i];
            abbe_five_input_q_t in;
            memset(&in, 0, sizeof in);
            memcpy(in.pos_nm, p->pos_nm, sizeof in.pos_nm);
            memcpy(in.angle_udeg, p->angle_udeg, sizeof in.angle_udeg);
            abbe_five_error_q_t out;
            assert_int_equal(abbe_five_error_eval_q(&m, &in, &out), ABBE_OK);
            for (int k = 0; k < 3; k++) {
                int64_t dp = diff_q(out.error_nm[k], p->expect_q_pm[k]);
                int64_t dr = diff_q(out.orient_nrad[k], p->expect_q_prad[k]);
                worst_pos = dp > worst_pos ? dp : worst_pos;
                worst_rot = dr > worst_rot ? dr : worst_rot;
                if (dp > ABBE_GOLDEN_FIVE_TOL_PM || dr > ABBE_GOLDEN_FIVE_TOL_PRAD) {
                    fail_msg("%s point %u comp %d: position %d nm vs %d pm, orientation %d nrad vs %d prad", g->name,
                             (unsigned)i, k, out.error_nm[k], p->expect_q_pm[k], out.orient_nrad[k],
                             p->expect_q_prad[k]);
                }
            }
        }
        printf("five-axis q %s (kind %u): worst |C - reference| position %lld pm, orientation %lld prad\n", g->name,
               (unsigned)g->kind, (long long)worst_pos, (long long)worst_rot);
        worst_pos = worst_pos > before_pos ? worst_pos : before_pos;
        worst_rot = worst_rot > before_rot ? worst_rot : before_rot;
    }
    printf("five-axis q: worst |C - reference| position %lld pm, orientation %lld prad\n", (long long)worst_pos,
           (long long)worst_rot);
}

/* A full turn is an exact period: the q result at C + k turns, tilt + k turns
 * is bit for bit the same. */
static void test_full_turn_exact(void **state)
{
    (void)state;
    for (unsigned t = 0; t < abbe_golden_five_table_count; t++) {
        abbe_five_model_t m;
        if (!load_five(t, &m)) {
            continue;
        }
        abbe_five_input_q_t in;
        memset(&in, 0, sizeof in);
        in.pos_nm[0] = 123456789;
        in.pos_nm[1] = -98765432;
        in.pos_nm[2] = -150000000;
        for (int32_t a = -359999999; a < 360000000; a += 7777777) {
            abbe_five_error_q_t ref, turned;
            in.angle_udeg[0] = a / 3;
            in.angle_udeg[1] = a;
            abbe_five_error_eval_q(&m, &in, &ref);
            for (int64_t k = -5; k <= 5; k++) {
                const int64_t c = (int64_t)a + k * 360000000, tl = (int64_t)(a / 3) - k * 360000000;
                if (k == 0 || c > INT32_MAX || c < INT32_MIN || tl > INT32_MAX || tl < INT32_MIN) {
                    continue;
                }
                in.angle_udeg[0] = (int32_t)tl;
                in.angle_udeg[1] = (int32_t)c;
                abbe_five_error_eval_q(&m, &in, &turned);
                assert_memory_equal(ref.error_nm, turned.error_nm, sizeof ref.error_nm);
                assert_memory_equal(ref.orient_nrad, turned.orient_nrad, sizeof ref.orient_nrad);
            }
        }
    }
}

/* The 3-axis loader refuses a five-axis table by its minor (it would
 * compensate half of it); the five-axis loader reads every 3-axis golden
 * table, and evaluates it exactly as the 3-axis evaluation does. */
static void test_three_axis_tables(void **state)
{
    (void)state;
    for (unsigned t = 0; t < abbe_golden_five_table_count; t++) {
        abbe_model_t m3;
        assert_int_equal(abbe_model_load(&m3, abbe_golden_five_tables[t].blob, abbe_golden_five_tables[t].blob_size),
                         ABBE_E_VERSION_MINOR);
    }
    for (uint32_t t = 0; t < abbe_golden_table_count; t++) {
        const abbe_golden_table_t *g = &abbe_golden_tables[t];
        abbe_model_t m3;
        abbe_five_model_t m5;
        assert_int_equal(abbe_model_load(&m3, g->blob, g->blob_size), ABBE_OK);
        assert_int_equal(abbe_five_model_load(&m5, g->blob, g->blob_size), ABBE_OK);
        assert_int_equal(abbe_five_model_kind(&m5), ABBE_KIN_NONE);
        for (uint32_t i = g->first_point; i < g->first_point + g->n_points; i++) {
            const abbe_golden_point_t *p = &abbe_golden_points[i];
            abbe_input_q_t in3;
            abbe_five_input_q_t in5;
            memcpy(in3.pos_nm, p->pos_nm, sizeof in3.pos_nm);
            memcpy(in3.dir_state_q30, p->dir_q30, sizeof in3.dir_state_q30);
            memcpy(in3.temp_mdegc, p->temp_mdegc, sizeof in3.temp_mdegc);
            memcpy(in5.pos_nm, p->pos_nm, sizeof in5.pos_nm);
            memcpy(in5.dir_state_q30, p->dir_q30, sizeof in5.dir_state_q30);
            memcpy(in5.temp_mdegc, p->temp_mdegc, sizeof in5.temp_mdegc);
            in5.angle_udeg[0] = 12345678;
            in5.angle_udeg[1] = -87654321;
            abbe_error_q_t o3;
            abbe_five_error_q_t o5;
            abbe_error_eval_q(&m3, &in3, &o3);
            abbe_five_error_eval_q(&m5, &in5, &o5);
            assert_memory_equal(o3.error_nm, o5.error_nm, sizeof o3.error_nm);
            assert_int_equal(o3.flags, o5.flags);
        }
    }
}

/* Each rotary-section defect is refused with its status, *model untouched. */
static void test_loader_refuses(void **state)
{
    (void)state;
    NEEDS_TRUNNIONS();
    const abbe_golden_five_table_t *g = &abbe_golden_five_tables[0];
    static uint8_t buf[4096] __attribute__((aligned(8)));
    assert_true(g->blob_size <= sizeof buf);
    struct {
        uint32_t offset;
        uint8_t value;
        abbe_status_t status;
    } cases[] = {
        {256u, 3u, ABBE_E_FLAGS},          /* kind */
        {256u, 0u, ABBE_E_FLAGS},          /* kind NONE with ROTARY */
        {257u, 1u, ABBE_E_FLAGS},          /* reserved header byte */
        {16u + 256u, 1u, ABBE_E_FLAGS},    /* AC: offset x (along A) */
        {320u + 22u, 1u, ABBE_E_FLAGS},    /* reserved axis byte */
        {320u + 63u, 1u, ABBE_E_FLAGS},    /* reserved axis byte */
        {320u + 20u, 0x40u, ABBE_E_COUNT}, /* comp_mask bit 6 */
        {320u + 21u, 9u, ABBE_E_COUNT},    /* harmonics 9 */
        {384u + 21u, 1u, ABBE_E_COUNT},    /* harmonics != coef_count */
        {320u + 27u, 0x7Fu, ABBE_E_OFFSET},/* coef_q offset out of the table */
        {320u + 11u, 0x40u, ABBE_E_RANGE}, /* a location angle > 2^28 */
        {256u + 7u, 0x40u, ABBE_E_RANGE},  /* rot_point beyond 2^30 nm */
        {20u, 0x60u, ABBE_E_FLAGS},        /* an unknown feature bit beside ROTARY */
        {6u, 1u, ABBE_E_FLAGS},            /* minor 1 does not know ROTARY */
    };
    for (size_t c = 0; c < sizeof cases / sizeof cases[0]; c++) {
        memcpy(buf, g->blob, g->blob_size);
        buf[cases[c].offset] = cases[c].value;
        tb_fix_crc(buf, g->blob_size);
        abbe_five_model_t m;
        memset(&m, 0xA5, sizeof m);
        abbe_five_model_t before = m;
        assert_int_equal(abbe_five_model_load(&m, buf, g->blob_size), cases[c].status);
        assert_memory_equal(&m, &before, sizeof m);
    }
    /* a float twin that is not its int32 converted; a NaN twin */
    memcpy(buf, g->blob, g->blob_size);
    uint32_t foff = tb_get_u32(buf + 320u + 28u);
    tb_put_u32(buf + foff, tb_get_u32(buf + foff) ^ 1u);
    tb_fix_crc(buf, g->blob_size);
    abbe_five_model_t m;
    assert_int_equal(abbe_five_model_load(&m, buf, g->blob_size), ABBE_E_MISMATCH);
    tb_put_u32(buf + foff, 0x7FC00000u);
    tb_fix_crc(buf, g->blob_size);
    assert_int_equal(abbe_five_model_load(&m, buf, g->blob_size), ABBE_E_NONFINITE);
    /* truncated, CRC */
    assert_int_equal(abbe_five_model_load(&m, g->blob, g->blob_size - 4u), ABBE_E_TRUNCATED);
    memcpy(buf, g->blob, g->blob_size);
    buf[300] ^= 1u;
    assert_int_equal(abbe_five_model_load(&m, buf, g->blob_size), ABBE_E_CRC);
    assert_int_equal(abbe_five_model_load(NULL, g->blob, g->blob_size), ABBE_E_ARG);
    assert_int_equal(abbe_five_model_load(&m, (const uint8_t *)g->blob + 1, g->blob_size - 1u), ABBE_E_ALIGN);
}

#if !defined(ABBE_NO_FIVE_KINDS)
/* The index of the head-head (kind 3) golden table; skips the test when the build leaves
 * kind 3 out (-DABBE_FIVE_KINDS). */
static unsigned golden_hh_index(void)
{
    if (ABBE_FIVE_KIND_BUILT(ABBE_KIN_XYZBC_HH) == 0u) {
        skip();
    }
    unsigned t = 0;
    while (abbe_golden_five_tables[t].kind != ABBE_KIN_XYZBC_HH) {
        t++;
        assert_true(t < abbe_golden_five_table_count);
    }
    return t;
}
#endif

#if !defined(ABBE_NO_FIVE_KINDS)
/* Kind 3 (head-head): the fixed-point evaluation keeps the head's lever as an int32 of
 * 2 nm, so the loader refuses |offset|_1 + |rot_point + offset|_1 beyond 2^32 - 2^10 nm
 * (ABBE_E_RANGE, docs/table-format.md), every component within its own cap (2^30 nm). At
 * the cap the table loads and the fixed-point error agrees with the float one (an int32
 * overflow there would be metres off); one nm more is refused, in either sign, *model
 * untouched. */
static void test_loader_hh_lever(void **state)
{
    (void)state;
    const unsigned t = golden_hh_index();
    const abbe_golden_five_table_t *g = &abbe_golden_five_tables[t];
    static uint8_t buf[4096] __attribute__((aligned(8)));
    assert_true(g->blob_size <= sizeof buf);
    /* offset (1 m, 0, 0), rot_point (1 m, 1 m, z): 1 m + (2 m + 1 m + |z|) */
    const int32_t cap_z = (int32_t)((((uint64_t)1 << 32) - 1024u) - 4000000000u);
    const struct {
        int32_t sign, z;
        abbe_status_t status;
    } cases[] = {{1, cap_z, ABBE_OK}, {1, cap_z + 1, ABBE_E_RANGE}, {-1, cap_z, ABBE_OK},
                 {-1, cap_z + 1, ABBE_E_RANGE}, {1, -cap_z - 1, ABBE_E_RANGE}};
    for (size_t c = 0; c < sizeof cases / sizeof cases[0]; c++) {
        memcpy(buf, g->blob, g->blob_size);
        const int32_t sg = cases[c].sign, rot_point[3] = {sg * 1000000000, sg * 1000000000, cases[c].z};
        const int32_t offset[3] = {sg * 1000000000, 0, 0};
        for (unsigned k = 0; k < 3u; k++) {
            tb_put_u32(buf + 256u + 4u + 4u * k, (uint32_t)rot_point[k]);
            tb_put_u32(buf + 256u + 16u + 4u * k, (uint32_t)offset[k]);
        }
        tb_fix_crc(buf, g->blob_size);
        abbe_five_model_t m;
        memset(&m, 0xA5, sizeof m);
        abbe_five_model_t before = m;
        assert_int_equal(abbe_five_model_load(&m, buf, g->blob_size), cases[c].status);
        if (cases[c].status != ABBE_OK) {
            assert_memory_equal(&m, &before, sizeof m);
            continue;
        }
        for (int32_t a = -180; a <= 180; a += 45) {
            abbe_five_input_q_t in;
            abbe_five_input_f32_t inf;
            memset(&in, 0, sizeof in);
            memset(&inf, 0, sizeof inf);
            in.pos_nm[0] = 100000000;
            inf.pos_mm[0] = 100.0f;
            in.angle_udeg[0] = a * 1000000;
            in.angle_udeg[1] = (a / 3) * 1000000;
            inf.angle_deg[0] = (float)a;
            inf.angle_deg[1] = (float)(a / 3);
            abbe_five_error_q_t out;
            abbe_five_error_f32_t outf;
            assert_int_equal(abbe_five_error_eval_q(&m, &in, &out), ABBE_OK);
            assert_int_equal(abbe_five_error_eval_f32(&m, &inf, &outf), ABBE_OK);
            for (int k = 0; k < 3; k++) {
                const double d = (double)out.error_nm[k] - (double)outf.error_um[k] * 1000.0;
                if (d > 100.0 || d < -100.0) {
                    fail_msg("angle %d comp %d: q %d nm, f32 %.3f um", (int)a, k, out.error_nm[k],
                             (double)outf.error_um[k]);
                }
            }
        }
    }
}
#endif

#if !defined(ABBE_NO_FIVE_KINDS)
/* A kind 3 model the loader would refuse (its head lever beyond HH_LEVER_L1_CAP, made in
 * memory): the lever L = -(g + R1 P1) is (2^31 - 2, 2^30 - 1) in 2 nm with B at 180 deg, and
 * C turns it beyond int32 near 45 deg (|L| = 1.118 x 2^31). The fixed-point evaluation
 * saturates the turned components and flags it (ABBE_FLAG_SATURATED; five_eval_q.c
 * rotate_sat_q), where an int32 conversion would wrap silently, at exactly the angles where
 * a turned component is beyond int32 on either side (a range test that let one side through
 * would fail here); the golden table as loaded never sets the flag. */
static void test_chain_turn_saturates(void **state)
{
    (void)state;
    const unsigned t = golden_hh_index();
    abbe_five_model_t m;
    assert_int_equal(load_five(t, &m), 1);
    unsigned flagged = 0, angles = 0;
    for (int pass = 0; pass < 2; pass++) {
        if (pass == 1) {
            const int32_t p0[3] = {0, -2147483646, 0}, p1[3] = {2147483646, 0, 0};
            memcpy(m.rot_point_nm, p0, sizeof p0);
            memcpy(m.tilt_pivot_nm, p1, sizeof p1);
        }
        for (int32_t a = -180; a < 180; a += 15) {
            abbe_five_input_q_t in;
            memset(&in, 0, sizeof in);
            in.angle_udeg[m.slot[0]] = a * 1000000;  /* record 0 (C) */
            in.angle_udeg[m.slot[1]] = 180000000;    /* record 1 (B) at 180 deg */
            abbe_five_error_q_t out;
            assert_int_equal(abbe_five_error_eval_q(&m, &in, &out), ABBE_OK);
            const unsigned sat = (out.flags & ABBE_FLAG_SATURATED) != 0u;
            if (pass == 0) {
                assert_int_equal(sat, 0);
            } else {
                flagged += sat;
                angles++;
                if (a % 90 != 0) { /* (at multiples of 90 deg a component is 2 LSB inside int32) */
                    /* the turned lever R_C (L0, L1) (chain_q: s0r, C's sine times record 0's sign):
                     * flagged exactly where a component is beyond int32, either side (every other
                     * angle is at least 2^26 from the bound) */
                    const double t = (double)a * 3.14159265358979323846 / 180.0;
                    const double L0 = 2147483646.0, L1 = 1073741823.0, c = cos(t);
                    const double s = m.sign[0] < 0 ? -sin(t) : sin(t);
                    const double x = c * L0 - s * L1, y = s * L0 + c * L1;
                    assert_int_equal(sat, (fabs(x) >= 2147483648.0 || fabs(y) >= 2147483648.0) ? 1u : 0u);
                }
            }
        }
    }
    /* near +/-45 and +/-135 deg the turned lever is beyond int32; at 0 and 180 it is not */
    assert_true(flagged >= 4u);
    assert_true(flagged < angles);
}
#endif

static abbe_comp_config_t config(void)
{
    abbe_comp_config_t c;
    memset(&c, 0, sizeof c);
    for (int j = 0; j < 3; j++) {
        c.warn_nm[j] = 500000;
        c.limit_nm[j] = 1000000;
        c.rate_nm_per_cycle[j] = 2000;
        c.axis_sign[j] = 1;
    }
    c.fade_cycles = 10;
    c.stale_cycles = 3;
    return c;
}

/* The compensator's five-axis step: after the fade its target is minus the
 * evaluation's position error (both variants), the orientation error is
 * reported, the output moves within the rate limit, a NaN angle is bad
 * input (held, then stale and faded out), and a queued model swaps at a
 * cycle boundary. */
static void test_comp_step5(void **state)
{
    (void)state;
    NEEDS_TRUNNIONS();
    static abbe_five_model_t m5, m5b;
    load_five(0, &m5);
    abbe_comp_t comp;
    abbe_comp_config_t cfg = config();
    assert_int_equal(abbe_comp_init(&comp, &cfg, NULL), ABBE_OK);
    assert_int_equal(abbe_comp_swap_five_model(&comp, &m5), ABBE_OK);
    assert_int_equal(abbe_comp_enable(&comp), ABBE_OK);
    const abbe_golden_five_point_t *p = &abbe_golden_five_points[abbe_golden_five_tables[0].first_point + 12u];
    abbe_comp_input5_q_t in;
    memset(&in, 0, sizeof in);
    memcpy(in.lin.pos_nm, p->pos_nm, sizeof in.lin.pos_nm);
    memcpy(in.angle_udeg, p->angle_udeg, sizeof in.angle_udeg);
    in.lin.fresh = 1;
    abbe_five_input_q_t ein;
    memset(&ein, 0, sizeof ein);
    memcpy(ein.pos_nm, p->pos_nm, sizeof ein.pos_nm);
    memcpy(ein.angle_udeg, p->angle_udeg, sizeof ein.angle_udeg);
    abbe_five_error_q_t e;
    abbe_five_error_eval_q(&m5, &ein, &e);
    abbe_comp_output5_t out;
    int32_t last[3] = {0, 0, 0};
    for (int cycle = 0; cycle < 400; cycle++) {
        assert_int_equal(abbe_comp_step5_q(&comp, &in, &out), ABBE_OK);
        for (int k = 0; k < 3; k++) {
            int32_t step = out.lin.corr_nm[k] - last[k];
            assert_true(step <= cfg.rate_nm_per_cycle[k] && step >= -cfg.rate_nm_per_cycle[k]);
            last[k] = out.lin.corr_nm[k];
        }
    }
    for (int k = 0; k < 3; k++) {
        assert_int_equal(out.lin.target_nm[k], -e.error_nm[k]);
        assert_int_equal(out.lin.corr_nm[k], -e.error_nm[k]);
        assert_int_equal(out.orient_nrad[k], e.orient_nrad[k]);
    }
    assert_true(e.orient_nrad[0] != 0 || e.orient_nrad[1] != 0 || e.orient_nrad[2] != 0);
    /* f32: the same target within the f32 bound (2 nm) */
    abbe_comp_input5_f32_t inf;
    memset(&inf, 0, sizeof inf);
    memcpy(inf.lin.pos_mm, p->pos_mm, sizeof inf.lin.pos_mm);
    memcpy(inf.angle_deg, p->angle_deg, sizeof inf.angle_deg);
    inf.lin.fresh = 1;
    assert_int_equal(abbe_comp_step5_f32(&comp, &inf, &out), ABBE_OK);
    for (int k = 0; k < 3; k++) {
        assert_true(abs(out.lin.target_nm[k] + e.error_nm[k]) <= 3);
        assert_true(abs(out.orient_nrad[k] - e.orient_nrad[k]) <= 3);
    }
    /* a NaN angle: bad input, the target is held, then stale and fading */
    inf.angle_deg[1] = (float)NAN;
    for (int cycle = 0; cycle < 3; cycle++) {
        abbe_comp_step5_f32(&comp, &inf, &out);
        assert_true(out.lin.flags & ABBE_FLAG_INPUT_INVALID);
    }
    assert_true(out.lin.flags & ABBE_FLAG_STALE);
    for (int cycle = 0; cycle < 400; cycle++) {
        abbe_comp_step5_f32(&comp, &inf, &out);
    }
    assert_int_equal(out.lin.corr_nm[0], 0);
    /* a queued model runs from the next cycle; a failing load keeps the running one */
    static uint8_t bad[4096] __attribute__((aligned(8)));
    memcpy(bad, abbe_golden_five_tables[1].blob, abbe_golden_five_tables[1].blob_size);
    bad[100] ^= 1u;
    assert_int_equal(abbe_comp_load_five_model(&comp, &m5b, bad, abbe_golden_five_tables[1].blob_size), ABBE_E_CRC);
    assert_ptr_equal(abbe_comp_model(&comp), &m5.linear);
    assert_int_equal(abbe_comp_load_five_model(&comp, &m5b, abbe_golden_five_tables[1].blob,
                                               abbe_golden_five_tables[1].blob_size),
                     ABBE_OK);
    assert_ptr_equal(abbe_comp_model(&comp), &m5.linear);
    abbe_comp_step5_q(&comp, &in, &out);
    assert_true(out.lin.flags & ABBE_FLAG_MODEL_SWAPPED);
    assert_ptr_equal(abbe_comp_model(&comp), &m5b.linear);
    assert_int_equal(abbe_comp_load_five_model(&comp, &m5b, abbe_golden_five_tables[1].blob,
                                               abbe_golden_five_tables[1].blob_size),
                     ABBE_E_ARG); /* the running slot */
}

/* A five-axis target beyond the error limit latches the fault: the output
 * fades out from where it was, monotonically, and stays 0 until reset. */
static void test_comp_step5_limit(void **state)
{
    (void)state;
    NEEDS_TRUNNIONS();
    static abbe_five_model_t m5;
    load_five(1, &m5); /* bc_motions: errors of some 100 um */
    abbe_comp_t comp;
    abbe_comp_config_t cfg = config();
    for (int k = 0; k < 3; k++) {
        cfg.warn_nm[k] = 1000;
        cfg.limit_nm[k] = 5000;
    }
    abbe_comp_init(&comp, &cfg, NULL);
    abbe_comp_swap_five_model(&comp, &m5);
    abbe_comp_enable(&comp);
    const abbe_golden_five_point_t *p = &abbe_golden_five_points[abbe_golden_five_tables[1].first_point + 20u];
    abbe_comp_input5_q_t in;
    memset(&in, 0, sizeof in);
    memcpy(in.lin.pos_nm, p->pos_nm, sizeof in.lin.pos_nm);
    memcpy(in.angle_udeg, p->angle_udeg, sizeof in.angle_udeg);
    in.lin.fresh = 1;
    abbe_comp_output5_t out;
    abbe_comp_step5_q(&comp, &in, &out);
    assert_true(abs(out.lin.target_nm[0]) > 5000 || abs(out.lin.target_nm[1]) > 5000 ||
                abs(out.lin.target_nm[2]) > 5000);
    assert_true(out.lin.flags & ABBE_FLAG_LIMIT);
    assert_int_equal(out.lin.state, ABBE_COMP_FAULT);
    for (int cycle = 0; cycle < 50; cycle++) {
        abbe_comp_step5_q(&comp, &in, &out);
        assert_int_equal(out.lin.state, ABBE_COMP_FAULT);
    }
    for (int k = 0; k < 3; k++) {
        assert_int_equal(out.lin.corr_nm[k], 0);
    }
}

/* Non-finite inputs of the float five-axis cycle: a NaN or infinite linear
 * position or angle, and (the thermal feature set) a NaN or infinite
 * temperature, is bad input: ABBE_FLAG_INPUT_INVALID, the target held
 * (docs/proofs.md: comp_five_f32_nonfinite proves no other runtime error for
 * any bits; that they are refused rests on this test and the hypotheses). */
static void test_comp_step5_nonfinite(void **state)
{
    (void)state;
    static abbe_five_model_t m5;
    const float bad[3] = {(float)NAN, (float)INFINITY, -(float)INFINITY};
    unsigned checked = 0, checked_temp = 0;
    for (unsigned t = 0; t < abbe_golden_five_table_count; t++) { /* every kind this library reads */
        if (load_five(t, &m5) == 0) {
            continue;
        }
        const abbe_golden_five_table_t *g = &abbe_golden_five_tables[t];
        const abbe_golden_five_point_t *p = &abbe_golden_five_points[g->first_point + g->n_points / 2u];
        for (unsigned slot = 0; slot < 8u; slot++) { /* X, Y, Z; tilt, C; the three temperatures */
            if (slot == 5u) {
                /* no five-axis golden table has the thermal feature: set it (its
                 * coefficients are the loader's zeros), so the temperatures are read */
                m5.linear.features |= ABBE_FEATURE_THERMAL;
            }
            for (unsigned b = 0; b < 3u; b++) {
                abbe_comp_t comp;
                abbe_comp_config_t cfg = config();
                assert_int_equal(abbe_comp_init(&comp, &cfg, NULL), ABBE_OK);
                assert_int_equal(abbe_comp_swap_five_model(&comp, &m5), ABBE_OK);
                assert_int_equal(abbe_comp_enable(&comp), ABBE_OK);
                abbe_comp_input5_f32_t in;
                memset(&in, 0, sizeof in);
                memcpy(in.lin.pos_mm, p->pos_mm, sizeof in.lin.pos_mm);
                memcpy(in.angle_deg, p->angle_deg, sizeof in.angle_deg);
                for (unsigned j = 0; j < 3u; j++) {
                    in.lin.temp_c[j] = 20.0f;
                }
                in.lin.fresh = 1;
                abbe_comp_output5_t good, out;
                assert_int_equal(abbe_comp_step5_f32(&comp, &in, &good), ABBE_OK);
                assert_false(good.lin.flags & ABBE_FLAG_INPUT_INVALID);
                if (slot < 3u) {
                    in.lin.pos_mm[slot] = bad[b];
                } else if (slot < 5u) {
                    in.angle_deg[slot - 3u] = bad[b];
                } else {
                    in.lin.temp_c[slot - 5u] = bad[b];
                    checked_temp++;
                }
                assert_int_equal(abbe_comp_step5_f32(&comp, &in, &out), ABBE_OK);
                assert_true(out.lin.flags & ABBE_FLAG_INPUT_INVALID);
                for (unsigned k = 0; k < 3u; k++) {
                    assert_int_equal(out.lin.target_nm[k], good.lin.target_nm[k]);
                }
                checked++;
            }
        }
    }
    print_message("step5_f32: %u non-finite inputs refused (%u temperatures)\n", checked, checked_temp);
    assert_true(checked >= 15u && checked_temp >= 9u);
}

/* A 3-axis model under the five-axis step gives the 3-axis correction. */
static void test_comp_step5_three_axis_model(void **state)
{
    (void)state;
    const abbe_golden_table_t *g = &abbe_golden_tables[0];
    static abbe_model_t m3;
    assert_int_equal(abbe_model_load(&m3, g->blob, g->blob_size), ABBE_OK);
    abbe_comp_t comp;
    abbe_comp_config_t cfg = config();
    abbe_comp_init(&comp, &cfg, &m3);
    const abbe_golden_point_t *p = &abbe_golden_points[g->first_point + 3u];
    abbe_comp_input5_q_t in;
    memset(&in, 0, sizeof in);
    memcpy(in.lin.pos_nm, p->pos_nm, sizeof in.lin.pos_nm);
    in.lin.fresh = 1;
    in.angle_udeg[1] = 90000000;
    abbe_input_q_t ein;
    memset(&ein, 0, sizeof ein);
    memcpy(ein.pos_nm, p->pos_nm, sizeof ein.pos_nm);
    abbe_error_q_t e;
    abbe_error_eval_q(&m3, &ein, &e);
    abbe_comp_output5_t out;
    abbe_comp_step5_q(&comp, &in, &out);
    for (int k = 0; k < 3; k++) {
        assert_int_equal(out.lin.target_nm[k], -e.error_nm[k]);
        assert_int_equal(out.orient_nrad[k], 0);
    }
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_kinds_built),
        cmocka_unit_test(test_golden_f32),
        cmocka_unit_test(test_golden_q),
        cmocka_unit_test(test_full_turn_exact),
        cmocka_unit_test(test_three_axis_tables),
        cmocka_unit_test(test_loader_refuses),
#if !defined(ABBE_NO_FIVE_KINDS)
        cmocka_unit_test(test_loader_hh_lever),
        cmocka_unit_test(test_chain_turn_saturates),
#endif
        cmocka_unit_test(test_comp_step5),
        cmocka_unit_test(test_comp_step5_limit),
        cmocka_unit_test(test_comp_step5_nonfinite),
        cmocka_unit_test(test_comp_step5_three_axis_model),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}

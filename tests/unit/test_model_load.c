/* Table validation: every malformed table gets its own status, never a crash
 * or an out-of-bounds read (ASan watches every case). */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#include <cmocka.h>

#include "abbe/abbe.h"
#include "blob_builder.h"

/* X: all six terms, trend degree 1, block 0 with 2 harmonics, block 1 with 1:
 * 1+1 + 4 + 2 = 8 rows x 6 columns. */
static int32_t coef_x[8 * 6];

static void base_table(tb_table_t *t)
{
    tb_init(t);
    for (int i = 0; i < 8 * 6; i++) {
        coef_x[i] = (i % 6 < 3) ? 2560000 * ((i % 5) - 2) : 3436 * ((i % 7) - 3) * 1000;
    }
    t->features = ABBE_FEATURE_SQUARENESS | ABBE_FEATURE_TOOL_OFFSET | ABBE_FEATURE_BACKLASH |
                  ABBE_FEATURE_THERMAL; /* every feature of format 1.0 */
    t->reference_nm[0] = 100000000;
    t->tool_nm[2] = 150000000;
    t->squareness_q36[0] = 687195; /* 10 urad */
    tb_axis_t *x = &t->axis[0];
    x->term_mask = 0x3F;
    x->trend_degree = 1;
    x->harmonics[0] = 2;
    x->harmonics[1] = 1;
    x->period_nm[0] = 1000000000;
    x->period_nm[1] = 10000000;
    x->origin_nm[1] = 5000;
    x->coef_q = coef_x;
    for (int j = 0; j < 3; j++) {
        t->axis[j].backlash_q8 = j == 0 ? 2560000 : 0;
        t->axis[j].takeup_nm = 1000000;
        t->axis[j].expansion_q50 = 13510799;
        t->axis[j].tref_mdegc = 20000;
    }
}

/* Format 1.1: the base table with reversal blocks on X (4 rows, after its
 * matrix) and Z (8 rows, an axis without terms: the block is its whole array). */
static int32_t rev_x[4], rev_z[8];

static void reversal_table(tb_table_t *t)
{
    base_table(t);
    t->features |= ABBE_FEATURE_REVERSAL;
    for (int k = 0; k < 4; k++) rev_x[k] = 256000 * (3 - 2 * k); /* 3, 1, -1, -3 um */
    for (int k = 0; k < 8; k++) rev_z[k] = 128000 * (k % 3 - 1);
    t->axis[0].reversal_rows = 4;
    t->axis[0].reversal_q = rev_x;
    t->axis[2].reversal_rows = 8;
    t->axis[2].reversal_q = rev_z;
}

static uint8_t blob[4096] __attribute__((aligned(8))); /* tables must be 4-byte aligned */

static size_t build_base(void)
{
    tb_table_t t;
    base_table(&t);
    size_t n = tb_build(&t, blob, sizeof blob);
    assert_true(n > 0);
    return n;
}

static size_t build_reversal(void)
{
    tb_table_t t;
    reversal_table(&t);
    size_t n = tb_build(&t, blob, sizeof blob);
    assert_true(n > 0);
    return n;
}

static abbe_status_t load(size_t n)
{
    abbe_model_t m;
    return abbe_model_load(&m, blob, n);
}

static void test_valid_table_loads(void **state)
{
    (void)state;
    size_t n = build_base();
    abbe_model_t m;
    assert_int_equal(abbe_model_load(&m, blob, n), ABBE_OK);
    assert_int_equal(abbe_model_size(&m), n);
    assert_int_equal(abbe_model_features(&m), 0xFu);
    assert_int_equal(abbe_model_crc(&m), tb_get_u32(blob + n - 4));
    /* extra bytes after the table (a flash sector) are ignored */
    assert_int_equal(abbe_model_load(&m, blob, n + 64), ABBE_OK);
    /* the per-axis facts a port needs (abbe_model_axis_info) */
    tb_table_t t;
    base_table(&t);
    for (unsigned j = 0; j < ABBE_AXES; j++) {
        abbe_axis_info_t info;
        assert_int_equal(abbe_model_axis_info(&m, j, &info), ABBE_OK);
        assert_int_equal(info.travel_min_nm, t.axis[j].travel_min_nm);
        assert_int_equal(info.travel_max_nm, t.axis[j].travel_max_nm);
        assert_int_equal(info.backlash_takeup_nm, t.axis[j].takeup_nm);
        assert_int_equal(info.thermal_tref_mdegc, t.axis[j].tref_mdegc);
    }
    abbe_axis_info_t info;
    assert_int_equal(abbe_model_axis_info(&m, ABBE_AXES, &info), ABBE_E_ARG);
    assert_int_equal(abbe_model_axis_info(NULL, 0, &info), ABBE_E_ARG);
    assert_int_equal(abbe_model_axis_info(&m, 0, NULL), ABBE_E_ARG);
}

static void test_null_arguments(void **state)
{
    (void)state;
    size_t n = build_base();
    abbe_model_t m;
    assert_int_equal(abbe_model_load(NULL, blob, n), ABBE_E_ARG);
    assert_int_equal(abbe_model_load(&m, NULL, n), ABBE_E_ARG);
}

/* Coefficients are read in place with word loads: a table at an odd address
 * is refused with its own status, whatever its content. */
static void test_misaligned_blob(void **state)
{
    (void)state;
    static uint8_t shifted[4100] __attribute__((aligned(8)));
    size_t n = build_base();
    for (size_t k = 1; k < 4; k++) {
        memcpy(shifted + k, blob, n);
        abbe_model_t m;
        assert_int_equal(abbe_model_load(&m, shifted + k, n), ABBE_E_ALIGN);
    }
    memcpy(shifted + 4, blob, n);
    abbe_model_t m;
    assert_int_equal(abbe_model_load(&m, shifted + 4, n), ABBE_OK);
}

/* Truncated at every byte: each shorter copy lives in its own exact-size heap
 * block, so ASan catches a single byte read past the end. */
static void expect_truncated_at_every_byte(size_t n)
{
    for (size_t len = 0; len < n; len++) {
        uint8_t *copy = malloc(len ? len : 1);
        assert_non_null(copy);
        memcpy(copy, blob, len);
        abbe_model_t m;
        assert_int_equal(abbe_model_load(&m, copy, len), ABBE_E_TRUNCATED);
        free(copy);
    }
}

static void test_truncated_at_every_byte(void **state)
{
    (void)state;
    expect_truncated_at_every_byte(build_base());
}

static void test_bad_magic(void **state)
{
    (void)state;
    size_t n = build_base();
    blob[1] = 'X';
    assert_int_equal(load(n), ABBE_E_MAGIC);
}

static void test_versions(void **state)
{
    (void)state;
    size_t n = build_base();
    blob[TB_H_MAJOR] = 2;
    assert_int_equal(load(n), ABBE_E_VERSION_MAJOR);
    n = build_base();
    blob[TB_H_MAJOR] = 0;
    assert_int_equal(load(n), ABBE_E_VERSION_MAJOR);
    n = build_base();
    blob[TB_H_MINOR] = 2; /* refused before the CRC is looked at */
    assert_int_equal(load(n), ABBE_E_VERSION_MINOR);
}

static void test_sizes(void **state)
{
    (void)state;
    size_t n = build_base();
    tb_put_u32(blob + TB_H_HEADER_SIZE, 60);
    assert_int_equal(load(n), ABBE_E_SIZE);
    n = build_base();
    tb_put_u32(blob + TB_H_AXIS_SIZE, 68);
    assert_int_equal(load(n), ABBE_E_SIZE);
    n = build_base();
    tb_put_u32(blob + TB_H_TOTAL, (uint32_t)n - 2); /* not a multiple of 4 */
    assert_int_equal(load(n), ABBE_E_SIZE);
    n = build_base();
    tb_put_u32(blob + TB_H_TOTAL, 100); /* below header + axis records + CRC */
    assert_int_equal(load(n), ABBE_E_SIZE);
}

static void test_crc(void **state)
{
    (void)state;
    size_t n = build_base();
    blob[300] ^= 0x01; /* a coefficient bit */
    assert_int_equal(load(n), ABBE_E_CRC);
    n = build_base();
    blob[n - 1] ^= 0x80; /* the CRC itself */
    assert_int_equal(load(n), ABBE_E_CRC);
}

/* Build a table (build_base / build_reversal), mutate a u32 or u8 field, fix the CRC,
 * expect a status. */
static void expect_field(size_t (*build)(void), size_t off, int width, uint32_t value,
                         abbe_status_t expected)
{
    size_t n = build();
    if (width == 4) {
        tb_put_u32(blob + off, value);
    } else {
        blob[off] = (uint8_t)value;
    }
    tb_fix_crc(blob, n);
    assert_int_equal(load(n), expected);
}

static void expect_u32(size_t off, uint32_t value, abbe_status_t expected)
{
    expect_field(build_base, off, 4, value, expected);
}

static void expect_u8(size_t off, uint8_t value, abbe_status_t expected)
{
    expect_field(build_base, off, 1, value, expected);
}

static void test_flags(void **state)
{
    (void)state;
    /* 0x10 (REVERSAL) is unknown to a 1.0 table */
    expect_u32(TB_H_FEATURES, 0xFu | ABBE_FEATURE_REVERSAL, ABBE_E_FLAGS);
    expect_u32(TB_H_RESERVED, 1, ABBE_E_FLAGS);
    expect_u32(TB_AXIS(1) + TB_A_REVERSAL_ROWS, 1, ABBE_E_FLAGS); /* reserved in 1.0 */
    /* a field set for a feature that is off */
    expect_u32(TB_H_FEATURES, ABBE_FEATURE_ALL & ~ABBE_FEATURE_TOOL_OFFSET, ABBE_E_FLAGS);
    expect_u32(TB_H_FEATURES, ABBE_FEATURE_ALL & ~ABBE_FEATURE_SQUARENESS, ABBE_E_FLAGS);
    expect_u32(TB_H_FEATURES, ABBE_FEATURE_ALL & ~ABBE_FEATURE_BACKLASH, ABBE_E_FLAGS);
    expect_u32(TB_H_FEATURES, ABBE_FEATURE_ALL & ~ABBE_FEATURE_THERMAL, ABBE_E_FLAGS);
}

static void test_counts_over_caps(void **state)
{
    (void)state;
    expect_u8(TB_AXIS(0) + TB_A_MASK, 0x7F, ABBE_E_COUNT);
    expect_u8(TB_AXIS(0) + TB_A_DEGREE, 8, ABBE_E_COUNT);
    expect_u8(TB_AXIS(0) + TB_A_DEGREE, 254, ABBE_E_COUNT);
    expect_u8(TB_AXIS(0) + TB_A_HARMONICS, 9, ABBE_E_COUNT);
    expect_u8(TB_AXIS(0) + TB_A_HARMONICS + 1, 200, ABBE_E_COUNT);
    expect_u32(TB_AXIS(0) + TB_A_COEF_COUNT, 47, ABBE_E_COUNT);
    expect_u32(TB_AXIS(0) + TB_A_COEF_COUNT, 0xFFFFFFFFu, ABBE_E_COUNT);
    /* an axis with no terms must declare no coefficients */
    expect_u32(TB_AXIS(2) + TB_A_COEF_COUNT, 6, ABBE_E_COUNT);
}

static void test_offsets_out_of_bounds(void **state)
{
    (void)state;
    size_t n = build_base();
    uint32_t off_f = tb_get_u32(blob + TB_AXIS(0) + TB_A_COEF_F32);
    expect_u32(TB_AXIS(0) + TB_A_COEF_Q, 0, ABBE_E_OFFSET);              /* inside the header */
    expect_u32(TB_AXIS(0) + TB_A_COEF_Q, 252, ABBE_E_OFFSET);            /* overlaps the axis records */
    expect_u32(TB_AXIS(0) + TB_A_COEF_Q, 258, ABBE_E_OFFSET);            /* misaligned */
    expect_u32(TB_AXIS(0) + TB_A_COEF_F32, off_f + 4, ABBE_E_OFFSET);    /* runs into the CRC */
    expect_u32(TB_AXIS(0) + TB_A_COEF_F32, (uint32_t)n, ABBE_E_OFFSET);  /* past the end */
    expect_u32(TB_AXIS(0) + TB_A_COEF_F32, 0xFFFFFFFCu, ABBE_E_OFFSET);  /* wraps 32 bits */
    expect_u32(TB_AXIS(1) + TB_A_COEF_Q, 256, ABBE_E_OFFSET);            /* offset with count 0 */
}

static void test_nonfinite_coefficients(void **state)
{
    (void)state;
    size_t n = build_base();
    uint32_t off_f = tb_get_u32(blob + TB_AXIS(0) + TB_A_COEF_F32);
    expect_u32(off_f + 4 * 5, 0x7FC00000u, ABBE_E_NONFINITE);  /* NaN */
    expect_u32(off_f, 0x7F800000u, ABBE_E_NONFINITE);          /* +Inf */
    expect_u32(off_f + 4 * 47, 0xFF800000u, ABBE_E_NONFINITE); /* -Inf, last element */
    (void)n;
}

/* The float32 array must be the int32 array converted, bit for bit (the fuzzer
 * found a finite 1e37 twin that made the float path overflow). */
static void test_float_twin_mismatch(void **state)
{
    (void)state;
    size_t n = build_base();
    uint32_t off_f = tb_get_u32(blob + TB_AXIS(0) + TB_A_COEF_F32);
    expect_u32(off_f + 4 * 7, tb_get_u32(blob + off_f + 4 * 7) ^ 1u, ABBE_E_MISMATCH); /* one ulp */
    expect_u32(off_f + 4 * 9, 0x7C4F1BBDu, ABBE_E_MISMATCH);                            /* 1.06e37 */
    (void)n;
}

/* The integer int32 -> float32 conversion of the loader is exact RNE, checked
 * against the compiler's conversion at the rounding boundaries. */
static void test_twin_conversion_rounding(void **state)
{
    (void)state;
    static const int32_t values[] = {1, -1, 16777216, 16777217, 16777218, 16777219, -16777219,
                                     33554435, 2147483647, -2147483647 - 1, 123456789, -987654321};
    static int32_t coef[6];
    for (size_t i = 0; i < sizeof values / sizeof values[0]; i++) {
        tb_table_t t;
        tb_init(&t);
        t.axis[1].term_mask = 1u << ABBE_TERM_DX;
        t.axis[1].trend_degree = 0;
        coef[0] = values[i];
        t.axis[1].coef_q = coef;
        size_t n = tb_build(&t, blob, sizeof blob); /* float twin written with (float)q */
        assert_int_equal(load(n), ABBE_OK);
    }
}

static void test_periods(void **state)
{
    (void)state;
    expect_u32(TB_AXIS(0) + TB_A_PERIOD, 0, ABBE_E_PERIOD);
    expect_u32(TB_AXIS(0) + TB_A_PERIOD + 4, (uint32_t)-5000000, ABBE_E_PERIOD);
    expect_u32(TB_AXIS(1) + TB_A_PERIOD, 1000000, ABBE_E_PERIOD); /* unused block with a period */
    expect_u32(TB_AXIS(1) + TB_A_ORIGIN + 4, 7, ABBE_E_PERIOD);   /* unused block with an origin */
}

static void test_travel(void **state)
{
    (void)state;
    expect_u32(TB_AXIS(1) + TB_A_MAX, 0, ABBE_E_TRAVEL);
    expect_u32(TB_AXIS(2) + TB_A_MIN, 600000000, ABBE_E_TRAVEL);
}

static void test_ranges(void **state)
{
    (void)state;
    expect_u32(TB_H_SQUARENESS + 4, (1u << 28) + 1u, ABBE_E_RANGE);
    expect_u32(TB_AXIS(0) + TB_A_TAKEUP, 0, ABBE_E_RANGE);          /* reversal without take-up */
    expect_u32(TB_AXIS(2) + TB_A_TAKEUP, (uint32_t)-1, ABBE_E_RANGE); /* negative take-up */
    expect_u32(TB_AXIS(2) + TB_A_TAKEUP, 0, ABBE_OK);               /* no reversal: 0 is fine */
    /* an angular coefficient sum over 2^28 (column 3, row 0) */
    tb_table_t t;
    base_table(&t);
    coef_x[3] = 1 << 28;
    size_t n = tb_build(&t, blob, sizeof blob);
    assert_int_equal(load(n), ABBE_E_RANGE);
    /* a linear coefficient of INT32_MIN: |c| = 2^31 alone is fine, three are not */
    base_table(&t);
    coef_x[0] = coef_x[6] = coef_x[12] = INT32_MIN;
    n = tb_build(&t, blob, sizeof blob);
    assert_int_equal(load(n), ABBE_E_RANGE);
    base_table(&t);
    coef_x[0] = INT32_MIN;
    n = tb_build(&t, blob, sizeof blob);
    assert_int_equal(load(n), ABBE_OK);
}

/* ---- format 1.1: reversal blocks ----------------------------------------- */

static void expect_u32_rev(size_t off, uint32_t value, abbe_status_t expected)
{
    expect_field(build_reversal, off, 4, value, expected);
}

static void expect_u8_rev(size_t off, uint8_t value, abbe_status_t expected)
{
    expect_field(build_reversal, off, 1, value, expected);
}

static void test_reversal_table_loads(void **state)
{
    (void)state;
    size_t n = build_reversal();
    assert_int_equal(blob[TB_H_MINOR], 1);
    abbe_model_t m;
    assert_int_equal(abbe_model_load(&m, blob, n), ABBE_OK);
    assert_int_equal(abbe_model_features(&m), ABBE_FEATURE_ALL);
    assert_int_equal(m.axis[0].reversal_rows, 4);
    assert_int_equal(m.axis[1].reversal_rows, 0);
    assert_int_equal(m.axis[2].reversal_rows, 8);
    /* the 1.0 base table, labelled 1.1, is a valid 1.1 table without blocks */
    n = build_base();
    blob[TB_H_MINOR] = 1;
    tb_fix_crc(blob, n);
    assert_int_equal(load(n), ABBE_OK);
}

/* A newer minor is refused before anything else is looked at; a 1.1 table
 * relabelled 1.0 uses what 1.0 does not have. */
static void test_reversal_versions(void **state)
{
    (void)state;
    expect_u8_rev(TB_H_MINOR, 2, ABBE_E_VERSION_MINOR);
    expect_u8_rev(TB_H_MINOR + 1, 1, ABBE_E_VERSION_MINOR); /* minor 257 */
    expect_u8_rev(TB_H_MINOR, 0, ABBE_E_FLAGS);
}

static void test_reversal_truncated_at_every_byte(void **state)
{
    (void)state;
    expect_truncated_at_every_byte(build_reversal());
}

static void test_reversal_flags(void **state)
{
    (void)state;
    expect_u32_rev(TB_H_FEATURES, ABBE_FEATURE_ALL | 0x20u, ABBE_E_FLAGS);      /* unknown in 1.1 */
    expect_u32_rev(TB_H_FEATURES, ABBE_FEATURE_ALL & ~ABBE_FEATURE_REVERSAL, ABBE_E_FLAGS); /* rows set */
    for (unsigned k = 1; k < 4; k++) {
        expect_u8_rev(TB_AXIS(0) + TB_A_REVERSAL_ROWS + k, 1, ABBE_E_FLAGS);   /* bytes 61..63 */
    }
    /* REVERSAL needs BACKLASH (its take-up and direction state), even with no rows */
    tb_table_t t;
    tb_init(&t);
    t.features = ABBE_FEATURE_REVERSAL;
    size_t n = tb_build(&t, blob, sizeof blob);
    assert_int_equal(load(n), ABBE_E_FLAGS);
    t.features = ABBE_FEATURE_REVERSAL | ABBE_FEATURE_BACKLASH;
    n = tb_build(&t, blob, sizeof blob);
    assert_int_equal(load(n), ABBE_OK);
}

static void test_reversal_counts(void **state)
{
    (void)state;
    expect_u8_rev(TB_AXIS(0) + TB_A_REVERSAL_ROWS, 9, ABBE_E_COUNT);
    expect_u8_rev(TB_AXIS(0) + TB_A_REVERSAL_ROWS, 255, ABBE_E_COUNT);
    expect_u8_rev(TB_AXIS(0) + TB_A_REVERSAL_ROWS, 3, ABBE_E_COUNT);  /* coef_count says 48 + 4 */
    expect_u32_rev(TB_AXIS(0) + TB_A_COEF_COUNT, 48, ABBE_E_COUNT);   /* the matrix alone */
    expect_u8_rev(TB_AXIS(1) + TB_A_REVERSAL_ROWS, 1, ABBE_E_COUNT);  /* a row Y does not store */
    expect_u32_rev(TB_AXIS(2) + TB_A_COEF_COUNT, 0, ABBE_E_COUNT);
}

static void test_reversal_offsets_and_values(void **state)
{
    (void)state;
    size_t n = build_reversal();
    uint32_t off_q = tb_get_u32(blob + TB_AXIS(2) + TB_A_COEF_Q);
    uint32_t off_f = tb_get_u32(blob + TB_AXIS(2) + TB_A_COEF_F32);
    assert_int_equal(off_f + 32u, n - 4u); /* Z's block is the last array */
    expect_u32_rev(TB_AXIS(2) + TB_A_COEF_F32, off_f + 4u, ABBE_E_OFFSET);  /* runs into the CRC */
    expect_u32_rev(TB_AXIS(2) + TB_A_COEF_Q, 0, ABBE_E_OFFSET);
    /* the reversal rows are coefficients like the others: finite twins, bit for bit */
    uint32_t x_f = tb_get_u32(blob + TB_AXIS(0) + TB_A_COEF_F32);
    expect_u32_rev(x_f + 4u * 49u, 0x7FC00000u, ABBE_E_NONFINITE);             /* X reversal row 1 */
    expect_u32_rev(off_f + 4u * 7u, 0xFF800000u, ABBE_E_NONFINITE);            /* Z row 7 */
    expect_u32_rev(x_f + 4u * 51u, tb_get_u32(blob + x_f + 4u * 51u) ^ 1u, ABBE_E_MISMATCH);
    expect_u32_rev(off_f + 4u, 0x3F800000u, ABBE_E_MISMATCH);                /* 1.0f for 0 */
    (void)off_q;
}

static void test_reversal_ranges(void **state)
{
    (void)state;
    /* a block needs a take-up distance even where B = 0 (Z) */
    expect_u32_rev(TB_AXIS(2) + TB_A_TAKEUP, 0, ABBE_E_RANGE);
    expect_u32_rev(TB_AXIS(1) + TB_A_TAKEUP, 0, ABBE_OK); /* Y: no reversal at all */
    /* |B| + sum |r_k| <= 2^31 */
    tb_table_t t;
    reversal_table(&t);
    t.axis[2].backlash_q8 = INT32_MIN; /* |B| = 2^31, plus 5 x 0.5 um of r_k: over */
    size_t n = tb_build(&t, blob, sizeof blob);
    assert_int_equal(load(n), ABBE_E_RANGE);
    static int32_t one[1];
    reversal_table(&t);
    t.axis[1].takeup_nm = 1000;
    t.axis[1].backlash_q8 = INT32_MIN + 1;
    t.axis[1].reversal_rows = 1;
    t.axis[1].reversal_q = one;
    one[0] = 1; /* 2^31 exactly: the cap */
    n = tb_build(&t, blob, sizeof blob);
    assert_int_equal(load(n), ABBE_OK);
    one[0] = -2;
    n = tb_build(&t, blob, sizeof blob);
    assert_int_equal(load(n), ABBE_E_RANGE);
}

/* A failed load leaves a model loaded earlier intact and usable. */
static void test_failure_keeps_previous_model(void **state)
{
    (void)state;
    size_t n = build_base();
    static uint8_t good[4096] __attribute__((aligned(8)));
    memcpy(good, blob, n);
    abbe_model_t m;
    assert_int_equal(abbe_model_load(&m, good, n), ABBE_OK);
    abbe_model_t before;
    memcpy(&before, &m, sizeof m);
    blob[n - 5] ^= 0xFF;
    assert_int_equal(abbe_model_load(&m, blob, n), ABBE_E_CRC);
    assert_memory_equal(&m, &before, sizeof m);
}

static void test_strerror_distinct(void **state)
{
    (void)state;
    for (int a = ABBE_STATUS_MIN; a <= ABBE_OK; a++) {
        const char *sa = abbe_strerror(a);
        assert_non_null(sa);
        assert_string_not_equal(sa, "unknown status");
        for (int b = a + 1; b <= ABBE_OK; b++) {
            assert_string_not_equal(sa, abbe_strerror(b));
        }
    }
    assert_string_equal(abbe_strerror(-999), "unknown status");
    assert_string_equal(abbe_strerror(ABBE_STATUS_MIN - 1), "unknown status");
}

static void test_crc32_reference_value(void **state)
{
    (void)state;
    assert_int_equal(abbe_crc32(0, "123456789", 9), 0xCBF43926u);
    /* chunked == whole */
    uint32_t c = abbe_crc32(0, "1234", 4);
    assert_int_equal(abbe_crc32(c, "56789", 5), 0xCBF43926u);
    assert_int_equal(abbe_crc32(0, "", 0), 0u);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_valid_table_loads),
        cmocka_unit_test(test_null_arguments),
        cmocka_unit_test(test_misaligned_blob),
        cmocka_unit_test(test_truncated_at_every_byte),
        cmocka_unit_test(test_bad_magic),
        cmocka_unit_test(test_versions),
        cmocka_unit_test(test_sizes),
        cmocka_unit_test(test_crc),
        cmocka_unit_test(test_flags),
        cmocka_unit_test(test_counts_over_caps),
        cmocka_unit_test(test_offsets_out_of_bounds),
        cmocka_unit_test(test_nonfinite_coefficients),
        cmocka_unit_test(test_float_twin_mismatch),
        cmocka_unit_test(test_twin_conversion_rounding),
        cmocka_unit_test(test_periods),
        cmocka_unit_test(test_travel),
        cmocka_unit_test(test_ranges),
        cmocka_unit_test(test_reversal_table_loads),
        cmocka_unit_test(test_reversal_versions),
        cmocka_unit_test(test_reversal_truncated_at_every_byte),
        cmocka_unit_test(test_reversal_flags),
        cmocka_unit_test(test_reversal_counts),
        cmocka_unit_test(test_reversal_offsets_and_values),
        cmocka_unit_test(test_reversal_ranges),
        cmocka_unit_test(test_failure_keeps_previous_model),
        cmocka_unit_test(test_strerror_distinct),
        cmocka_unit_test(test_crc32_reference_value),
    };
    return cmocka_run_group_tests_name("model_load", tests, NULL, NULL);
}

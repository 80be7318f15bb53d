/* The thermal runtime (format 1.3, abbe/thermal.h): the loader's checks (every
 * status), the golden vectors of the Python reference (abbe.model.thermal),
 * and the fault handling: hold, fade out, flag, catch up, fade in, no jump. */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>
#include <string.h>

#include <cmocka.h>

#include "abbe/abbe.h"
#include "golden_data.h"
#include "golden_thermal.h"

#define BLOB_MAX 8192u
typedef union { uint32_t align; uint8_t b[BLOB_MAX]; } blob_buf_t;

static const abbe_golden_thermal_sample_t *S = abbe_golden_thermal_samples;

static void put_u32(uint8_t *p, uint32_t v)
{
    p[0] = (uint8_t)v; p[1] = (uint8_t)(v >> 8); p[2] = (uint8_t)(v >> 16); p[3] = (uint8_t)(v >> 24);
}

static uint32_t get_u32(const uint8_t *p)
{
    return (uint32_t)p[0] | (uint32_t)p[1] << 8 | (uint32_t)p[2] << 16 | (uint32_t)p[3] << 24;
}

static void fix_crc(uint8_t *b)
{
    uint32_t total = get_u32(b + 8);
    put_u32(b + total - 4u, abbe_crc32(0, b, total - 4u));
}

static void copy_golden(blob_buf_t *buf)
{
    assert_true(abbe_golden_thermal_blob_size <= BLOB_MAX);
    memcpy(buf->b, abbe_golden_thermal_blob, abbe_golden_thermal_blob_size);
}

static uint32_t block_off(const blob_buf_t *buf)
{
    return get_u32(buf->b + 60);
}

static abbe_status_t load(const blob_buf_t *buf)
{
    abbe_model_t m;
    abbe_thermal_model_t th;
    return abbe_thermal_load(&m, &th, buf->b, abbe_golden_thermal_blob_size);
}

static void test_loaders(void **state)
{
    (void)state;
    abbe_model_t m;
    abbe_five_model_t f;
    abbe_thermal_model_t th;
    /* the golden 1.3 table: older loaders refuse it by its minor */
    assert_int_equal(abbe_model_load(&m, abbe_golden_thermal_blob, abbe_golden_thermal_blob_size),
                     ABBE_E_VERSION_MINOR);
    assert_int_equal(abbe_five_model_load(&f, abbe_golden_thermal_blob, abbe_golden_thermal_blob_size),
                     ABBE_E_VERSION_MINOR);
    assert_int_equal(abbe_thermal_load(&m, &th, abbe_golden_thermal_blob, abbe_golden_thermal_blob_size), ABBE_OK);
    assert_int_equal(abbe_thermal_n_inputs(&th), 17);
    assert_int_equal(abbe_thermal_n_channels(&th), 5);
    assert_int_equal(abbe_model_crc(&m), get_u32(abbe_golden_thermal_blob + abbe_golden_thermal_blob_size - 4u));
    /* every older 3-axis table loads, without a thermal block */
    for (uint32_t t = 0; t < abbe_golden_table_count; t++) {
        abbe_model_t ref;
        assert_int_equal(abbe_thermal_load(&m, &th, abbe_golden_tables[t].blob, abbe_golden_tables[t].blob_size),
                         ABBE_OK);
        assert_int_equal(abbe_model_load(&ref, abbe_golden_tables[t].blob, abbe_golden_tables[t].blob_size), ABBE_OK);
        assert_int_equal(abbe_thermal_n_channels(&th), 0);
        assert_int_equal(abbe_model_crc(&m), abbe_model_crc(&ref));
    }
}

typedef struct {
    const char *what;
    unsigned where;     /* 0: header offset, 1: thermal block offset */
    uint32_t off;
    uint32_t size;      /* 1, 2 or 4 bytes */
    uint32_t value;
    abbe_status_t expect;
} mutation_t;

/* Thermal block layout: header 16 (n_in, n_ch, res16, gap, fade, res32),
 * 17 inputs x 20 (kind, res[3], ref, min, max, step), channels x 56
 * (output, n_terms, res16, limit, 4 x {input, res[3], tau, gain}). */
#define IN(k, f) (16u + 20u * (k) + (f))
#define CH(c, f) (16u + 20u * 17u + 56u * (c) + (f))
static const mutation_t MUTATIONS[] = {
    {"minor 4", 0, 6, 2, 4, ABBE_E_VERSION_MINOR},
    {"feature bit 7", 0, 20, 4, 0x40u | 0x80u | 0x1Fu, ABBE_E_FLAGS},
    {"ROTARY bit", 0, 20, 4, 0x40u | 0x20u | 0x1Fu, ABBE_E_FLAGS},
    {"offset misaligned", 0, 60, 4, 0x102u, ABBE_E_OFFSET},
    {"offset below the data", 0, 60, 4, 252u, ABBE_E_OFFSET},
    {"offset past the end", 0, 60, 4, 0x7FFFFFF0u, ABBE_E_OFFSET},
    {"0 inputs", 1, 0, 1, 0, ABBE_E_COUNT},
    {"18 inputs", 1, 0, 1, 18, ABBE_E_COUNT},
    {"6 channels", 1, 1, 1, 6, ABBE_E_COUNT},
    {"header reserved", 1, 12, 4, 1, ABBE_E_FLAGS},
    {"kind 2", 1, IN(3, 0), 1, 2, ABBE_E_FLAGS},
    {"input reserved", 1, IN(3, 2), 1, 1, ABBE_E_FLAGS},
    {"stuck resolution without a stuck time", 1, IN(3, 2), 2, 20, ABBE_E_FLAGS},
    {"output 5", 1, CH(2, 0), 1, 5, ABBE_E_FLAGS},
    {"output twice", 1, CH(2, 0), 1, 0, ABBE_E_FLAGS},
    {"term reserved", 1, CH(1, 8 + 1), 1, 1, ABBE_E_FLAGS},
    {"0 terms", 1, CH(1, 1), 1, 0, ABBE_E_FLAGS}, /* the slots then hold unused terms */
    {"5 terms", 1, CH(1, 1), 1, 5, ABBE_E_COUNT},
    {"term input 17", 1, CH(1, 8), 1, 17, ABBE_E_COUNT},
    {"max_gap 0", 1, 4, 4, 0, ABBE_E_RANGE},
    {"fade over 2^31 ms", 1, 8, 4, 0x80000001u, ABBE_E_RANGE},
    {"reference over 2^20", 1, IN(0, 4), 4, 0x00100001u, ABBE_E_RANGE},
    {"valid_min >= valid_max", 1, IN(0, 8), 4, 90000u, ABBE_E_RANGE},
    {"max_step 0", 1, IN(5, 16), 4, 0, ABBE_E_RANGE},
    {"limit 0", 1, CH(4, 4), 4, 0, ABBE_E_RANGE},
    {"gain over 2^28", 1, CH(4, 8 + 8), 4, 0x10000001u, ABBE_E_RANGE},
    {"tau over 2^31 ms", 1, CH(4, 8 + 4), 4, 0x80000001u, ABBE_E_RANGE},
};

static void test_every_status(void **state)
{
    (void)state;
    blob_buf_t buf;
    abbe_model_t m;
    abbe_thermal_model_t th;
    copy_golden(&buf);
    assert_int_equal(abbe_thermal_load(NULL, &th, buf.b, abbe_golden_thermal_blob_size), ABBE_E_ARG);
    assert_int_equal(abbe_thermal_load(&m, NULL, buf.b, abbe_golden_thermal_blob_size), ABBE_E_ARG);
    assert_int_equal(abbe_thermal_load(&m, &th, NULL, 0), ABBE_E_ARG);
    assert_int_equal(abbe_thermal_load(&m, &th, buf.b + 1, abbe_golden_thermal_blob_size - 1u), ABBE_E_ALIGN);
    assert_int_equal(abbe_thermal_load(&m, &th, buf.b, abbe_golden_thermal_blob_size - 4u), ABBE_E_TRUNCATED);
    buf.b[0] = 'X';
    assert_int_equal(load(&buf), ABBE_E_MAGIC);
    copy_golden(&buf);
    buf.b[4] = 2;
    assert_int_equal(load(&buf), ABBE_E_VERSION_MAJOR);
    copy_golden(&buf);
    buf.b[12] = 60;
    assert_int_equal(load(&buf), ABBE_E_SIZE);
    copy_golden(&buf);
    buf.b[block_off(&buf) + 4u] ^= 1u;
    assert_int_equal(load(&buf), ABBE_E_CRC);
    /* the geometric part's own checks, through the thermal loader (X record at 64) */
    copy_golden(&buf);
    put_u32(buf.b + 64 + 4, get_u32(buf.b + 64)); /* travel_max = travel_min */
    fix_crc(buf.b);
    assert_int_equal(load(&buf), ABBE_E_TRAVEL);
    copy_golden(&buf);
    assert_true(buf.b[64 + 10] > 0u); /* block 0 used: its period must be > 0 */
    put_u32(buf.b + 64 + 12, 0u);
    fix_crc(buf.b);
    assert_int_equal(load(&buf), ABBE_E_PERIOD);
    copy_golden(&buf);
    put_u32(buf.b + get_u32(buf.b + 64 + 52), 0x7FC00000u); /* first float32 coefficient: NaN */
    fix_crc(buf.b);
    assert_int_equal(load(&buf), ABBE_E_NONFINITE);
    copy_golden(&buf);
    buf.b[get_u32(buf.b + 64 + 52)] ^= 1u; /* no longer its int32 twin */
    fix_crc(buf.b);
    assert_int_equal(load(&buf), ABBE_E_MISMATCH);
    /* a minor-2 table may not set THERMAL_DYN */
    copy_golden(&buf);
    buf.b[6] = 2;
    fix_crc(buf.b);
    assert_int_equal(load(&buf), ABBE_E_FLAGS);
    for (size_t i = 0; i < sizeof MUTATIONS / sizeof MUTATIONS[0]; i++) {
        const mutation_t *mu = &MUTATIONS[i];
        copy_golden(&buf);
        uint8_t *p = buf.b + (mu->where != 0u ? block_off(&buf) : 0u) + mu->off;
        for (uint32_t k = 0; k < mu->size; k++) {
            p[k] = (uint8_t)(mu->value >> (8u * k));
        }
        fix_crc(buf.b);
        abbe_thermal_model_t before;
        memset(&before, 0xA5, sizeof before);
        th = before;
        abbe_status_t st = abbe_thermal_load(&m, &th, buf.b, abbe_golden_thermal_blob_size);
        if (st != mu->expect) {
            print_error("mutation '%s': status %d, expected %d\n", mu->what, (int)st, (int)mu->expect);
        }
        assert_int_equal(st, mu->expect);
        assert_memory_equal(&th, &before, sizeof th); /* untouched on failure */
    }
}

static int64_t tol(int64_t abs_nm, float rel, int32_t ref)
{
    int64_t r = ref < 0 ? -(int64_t)ref : ref;
    return abs_nm + (int64_t)((float)r * rel) + 1;
}

static int64_t absdiff(int64_t a, int64_t b)
{
    return a > b ? a - b : b - a;
}

static void test_golden_f32(void **state)
{
    (void)state;
    abbe_model_t m;
    abbe_thermal_model_t th;
    abbe_thermal_state_t st;
    assert_int_equal(abbe_thermal_load(&m, &th, abbe_golden_thermal_blob, abbe_golden_thermal_blob_size), ABBE_OK);
    /* one apply() per sample, its period the fade time: every fade is one step */
    assert_int_equal(abbe_thermal_init_f32(&st, &th, 30.0f), ABBE_OK);
    int64_t worst = 0;
    for (uint32_t n = 0; n < abbe_golden_thermal_sample_count; n++) {
        assert_int_equal(abbe_thermal_update_f32(&st, S[n].x, 0x1FFFFu, n ? S[n].dt_s : 0.0f), ABBE_OK);
        float err[3] = {0.0f, 0.0f, 0.0f};
        abbe_thermal_apply_f32(&st, err);
        float y[ABBE_THERMAL_MAX_CHANNELS];
        assert_int_equal(abbe_thermal_channels_f32(&st, y), 5);
        for (unsigned c = 0; c < 5u; c++) {
            int64_t d = absdiff((int64_t)((double)y[c] * 1000.0), S[n].expect_f32[c]);
            worst = d > worst ? d : worst;
            assert_true(d <= tol(ABBE_GOLDEN_THERMAL_TOL_F32_ABS_NM, ABBE_GOLDEN_THERMAL_TOL_F32_REL, S[n].expect_f32[c]));
        }
        for (unsigned a = 0; a < 3u; a++) {
            int64_t d = absdiff((int64_t)((double)err[a] * 1000.0), S[n].tip_f32_nm[a]);
            assert_true(d <= tol(ABBE_GOLDEN_THERMAL_TOL_F32_ABS_NM, ABBE_GOLDEN_THERMAL_TOL_F32_REL, S[n].tip_f32_nm[a]) + 1);
        }
        assert_int_equal(abbe_thermal_flags(&st) & ABBE_THERMAL_F_FAULTS, 0u);
    }
    print_message("thermal golden f32: worst channel difference %lld nm\n", (long long)worst);
}

static void test_golden_q(void **state)
{
    (void)state;
    abbe_model_t m;
    abbe_thermal_model_t th;
    abbe_thermal_state_t st;
    assert_int_equal(abbe_thermal_load(&m, &th, abbe_golden_thermal_blob, abbe_golden_thermal_blob_size), ABBE_OK);
    assert_int_equal(abbe_thermal_init_q(&st, &th, 30000000u), ABBE_OK);
    int64_t worst = 0;
    for (uint32_t n = 0; n < abbe_golden_thermal_sample_count; n++) {
        assert_int_equal(abbe_thermal_update_q(&st, S[n].x_milli, 0x1FFFFu, n ? S[n].dt_ms : 0u), ABBE_OK);
        int32_t err[3] = {0, 0, 0};
        abbe_thermal_apply_q(&st, err);
        int32_t y[ABBE_THERMAL_MAX_CHANNELS];
        assert_int_equal(abbe_thermal_channels_q(&st, y), 5);
        for (unsigned c = 0; c < 5u; c++) {
            int64_t d = absdiff(y[c], S[n].expect_q[c]);
            worst = d > worst ? d : worst;
            assert_true(d <= tol(ABBE_GOLDEN_THERMAL_TOL_Q_ABS_NM, ABBE_GOLDEN_THERMAL_TOL_Q_REL, S[n].expect_q[c]));
        }
        for (unsigned a = 0; a < 3u; a++) {
            assert_true(absdiff(err[a], S[n].tip_q_nm[a]) <=
                        tol(ABBE_GOLDEN_THERMAL_TOL_Q_ABS_NM, ABBE_GOLDEN_THERMAL_TOL_Q_REL, S[n].tip_q_nm[a]) + 1);
        }
    }
    print_message("thermal golden q: worst channel difference %lld nm\n", (long long)worst);
}

/* ---- faults: the golden record at 1 s evaluation periods, with faults injected ---- */
enum { F_NONE, F_OPEN, F_RANGE, F_STEP, F_GAP };
typedef struct { uint32_t from, to; unsigned kind; } fault_t;
static const fault_t FAULTS[] = {
    {40, 48, F_OPEN}, {90, 92, F_RANGE}, {130, 131, F_STEP}, {170, 171, F_GAP},
};
#define FAULT_INPUT 5u /* a temperature some channels read and others do not */

typedef struct { float max_step[3]; uint32_t events; float y_end[5]; float out_end[3]; uint32_t hold_seen; } run_result_t;

static unsigned fault_at(uint32_t n)
{
    for (size_t i = 0; i < sizeof FAULTS / sizeof FAULTS[0]; i++) {
        if (n >= FAULTS[i].from && n < FAULTS[i].to) {
            return FAULTS[i].kind;
        }
    }
    return F_NONE;
}

static run_result_t run_f32(int with_faults)
{
    abbe_model_t m;
    abbe_thermal_model_t th;
    abbe_thermal_state_t st;
    run_result_t r;
    memset(&r, 0, sizeof r);
    assert_int_equal(abbe_thermal_load(&m, &th, abbe_golden_thermal_blob, abbe_golden_thermal_blob_size), ABBE_OK);
    assert_int_equal(abbe_thermal_init_f32(&st, &th, 1.0f), ABBE_OK);
    float prev[3] = {0.0f, 0.0f, 0.0f};
    for (uint32_t n = 0; n < abbe_golden_thermal_sample_count; n++) {
        unsigned kind = with_faults ? fault_at(n) : F_NONE;
        uint32_t calls = n ? (uint32_t)S[n].dt_s : 0u;
        if (kind == F_GAP) {
            calls += 200u; /* samples lost: 200 s more than max_gap (120 s) */
        }
        for (uint32_t k = 0; k < calls; k++) {
            float err[3] = {0.0f, 0.0f, 0.0f};
            abbe_thermal_apply_f32(&st, err);
            for (unsigned a = 0; a < 3u; a++) {
                float d = err[a] - prev[a];
                d = d < 0.0f ? -d : d;
                r.max_step[a] = d > r.max_step[a] ? d : r.max_step[a];
                prev[a] = err[a];
            }
        }
        float x[17];
        memcpy(x, S[n].x, sizeof x);
        uint32_t valid = 0x1FFFFu;
        if (kind == F_OPEN) valid &= ~(1u << FAULT_INPUT);
        if (kind == F_RANGE) x[FAULT_INPUT] = 850.0f; /* a broken thermocouple's reading */
        if (kind == F_STEP) x[FAULT_INPUT] += 9.0f;
        float dt = n ? S[n].dt_s + (kind == F_GAP ? 200.0f : 0.0f) : 0.0f;
        assert_int_equal(abbe_thermal_update_f32(&st, x, valid, dt), ABBE_OK);
        uint32_t f = abbe_thermal_flags(&st);
        if (kind == F_OPEN) assert_true(f & ABBE_THERMAL_F_OPEN);
        if (kind == F_RANGE) assert_true(f & ABBE_THERMAL_F_RANGE);
        if (kind == F_STEP) assert_true(f & ABBE_THERMAL_F_STEP);
        if (kind == F_GAP) assert_true(f & ABBE_THERMAL_F_GAP);
        if (kind == F_OPEN || kind == F_RANGE || kind == F_STEP) {
            assert_int_equal(abbe_thermal_input_faults(&st), 1u << FAULT_INPUT);
        }
        /* a spike is two steps: away from the last reading and back to it */
        if (kind == F_NONE && !(n > 0u && fault_at(n - 1u) == F_STEP && with_faults)) {
            assert_int_equal(f & ABBE_THERMAL_F_FAULTS, 0u);
        }
        r.hold_seen |= f & ABBE_THERMAL_F_HOLD;
        r.events |= abbe_thermal_events(&st);
    }
    for (uint32_t k = 0; k < 60u; k++) { /* let every fade finish */
        float err[3] = {0.0f, 0.0f, 0.0f};
        abbe_thermal_apply_f32(&st, err);
        memcpy(r.out_end, err, sizeof err);
    }
    abbe_thermal_channels_f32(&st, r.y_end);
    return r;
}

static void test_faults_f32(void **state)
{
    (void)state;
    run_result_t clean = run_f32(0), faulty = run_f32(1);
    assert_int_equal(clean.events & (ABBE_THERMAL_F_FAULTS | ABBE_THERMAL_F_HOLD), 0u);
    /* every fault but stuck (the golden block has no stuck check: test_stuck) */
    assert_int_equal(faulty.events & ABBE_THERMAL_F_FAULTS, ABBE_THERMAL_F_FAULTS & ~ABBE_THERMAL_F_STUCK);
    assert_true(faulty.hold_seen);
    /* Nothing jumps: the largest change per evaluation with faults is at most the
     * clean run's (a sample's own lag increment) plus one fade step of the
     * largest tool tip contribution (400 um limit x 5 channels / 30 s at 1 s). */
    for (unsigned a = 0; a < 3u; a++) {
        print_message("axis %u: largest step per evaluation clean %.4f um, with faults %.4f um\n", a,
                      (double)clean.max_step[a], (double)faulty.max_step[a]);
        float sum_y = 0.0f; /* one fade step of every channel at its size: |y| / 30 s x 1 s */
        for (unsigned c = 0; c < 5u; c++) {
            sum_y += clean.y_end[c] < 0.0f ? -clean.y_end[c] : clean.y_end[c];
        }
        assert_true(faulty.max_step[a] <= clean.max_step[a] + 2.0f * sum_y / 30.0f);
    }
    /* channels that do not read the faulted input never noticed; the others came back */
    abbe_model_t m;
    abbe_thermal_model_t th;
    assert_int_equal(abbe_thermal_load(&m, &th, abbe_golden_thermal_blob, abbe_golden_thermal_blob_size), ABBE_OK);
    for (unsigned c = 0; c < 5u; c++) {
        float d = faulty.y_end[c] - clean.y_end[c];
        d = d < 0.0f ? -d : d;
        print_message("channel %u (reads the faulted input: %d): end value clean %.3f, with faults %.3f\n", c,
                      (th.channel_inputs[c] >> FAULT_INPUT) & 1u, (double)clean.y_end[c], (double)faulty.y_end[c]);
        /* the held time is caught up in one backward Euler step: close, not equal */
        assert_true(d < 0.05f * (clean.y_end[c] < 0.0f ? -clean.y_end[c] : clean.y_end[c]) + 0.5f);
    }
    for (unsigned a = 0; a < 3u; a++) { /* faded back in completely */
        float d = faulty.out_end[a] - clean.out_end[a];
        d = d < 0.0f ? -d : d;
        assert_true(d < 0.05f * (clean.out_end[a] < 0.0f ? -clean.out_end[a] : clean.out_end[a]) + 0.5f);
    }
}

/* The fade itself: a fault fades the output out linearly over fade_s, no faster */
static void test_fade_rate_q(void **state)
{
    (void)state;
    abbe_model_t m;
    abbe_thermal_model_t th;
    abbe_thermal_state_t st;
    assert_int_equal(abbe_thermal_load(&m, &th, abbe_golden_thermal_blob, abbe_golden_thermal_blob_size), ABBE_OK);
    assert_int_equal(abbe_thermal_init_q(&st, &th, 1000000u), ABBE_OK); /* 1 s periods; fade 30 s */
    int32_t err[3];
    for (uint32_t n = 0; n < 20u; n++) {
        assert_int_equal(abbe_thermal_update_q(&st, S[n].x_milli, 0x1FFFFu, n ? S[n].dt_ms : 0u), ABBE_OK);
        for (uint32_t k = 0; k < 40u; k++) {
            memset(err, 0, sizeof err);
            abbe_thermal_apply_q(&st, err);
        }
    }
    assert_int_equal(abbe_thermal_flags(&st) & (ABBE_THERMAL_F_FADING | ABBE_THERMAL_F_HOLD), 0u);
    int32_t full[3];
    memcpy(full, err, sizeof full);
    assert_true(full[0] != 0 && full[1] != 0 && full[2] != 0);
    /* the speed input (16) opens: every channel reads it and fades out */
    assert_int_equal(abbe_thermal_update_q(&st, S[20].x_milli, 0x0FFFFu, S[20].dt_ms), ABBE_OK);
    assert_true(abbe_thermal_flags(&st) & ABBE_THERMAL_F_HOLD);
    for (uint32_t k = 1; k <= 31u; k++) {
        memset(err, 0, sizeof err);
        abbe_thermal_apply_q(&st, err);
        for (unsigned a = 0; a < 3u; a++) {
            int64_t expect = (int64_t)full[a] * (30 - (int64_t)(k > 30u ? 30u : k)) / 30;
            assert_true(absdiff(err[a], expect) <= 2 + (full[a] < 0 ? -full[a] : full[a]) / 1000);
        }
    }
    assert_int_equal(err[0], 0);
    assert_int_equal(abbe_thermal_flags(&st) & ABBE_THERMAL_F_FADING, 0u);
    /* good again: catch up once faded out, then fade back in over 30 s */
    assert_int_equal(abbe_thermal_update_q(&st, S[21].x_milli, 0x1FFFFu, S[21].dt_ms), ABBE_OK);
    assert_true(abbe_thermal_flags(&st) & ABBE_THERMAL_F_FADING);
    assert_false(abbe_thermal_flags(&st) & ABBE_THERMAL_F_HOLD);
    memset(err, 0, sizeof err);
    abbe_thermal_apply_q(&st, err);
    int32_t y[5];
    abbe_thermal_channels_q(&st, y);
    assert_true(err[0] != 0);
    /* the watchdog: no sample for max_gap (120 s) fades everything out and flags GAP */
    abbe_thermal_clear_events(&st);
    for (uint32_t k = 0; k < 200u; k++) {
        memset(err, 0, sizeof err);
        abbe_thermal_apply_q(&st, err);
    }
    assert_true(abbe_thermal_events(&st) & ABBE_THERMAL_F_GAP);
    assert_int_equal(err[0], 0);
    assert_int_equal(err[1], 0);
    assert_int_equal(err[2], 0);
}

static void test_args(void **state)
{
    (void)state;
    abbe_model_t m;
    abbe_thermal_model_t th;
    abbe_thermal_state_t st;
    assert_int_equal(abbe_thermal_load(&m, &th, abbe_golden_thermal_blob, abbe_golden_thermal_blob_size), ABBE_OK);
    assert_int_equal(abbe_thermal_init_f32(NULL, &th, 1.0f), ABBE_E_ARG);
    assert_int_equal(abbe_thermal_init_f32(&st, &th, 0.0f), ABBE_E_ARG);
    assert_int_equal(abbe_thermal_init_q(&st, &th, 0u), ABBE_E_ARG);
    assert_int_equal(abbe_thermal_init_f32(&st, &th, 0.001f), ABBE_OK);
    assert_int_equal(abbe_thermal_update_f32(&st, NULL, 0u, 1.0f), ABBE_E_ARG);
    assert_int_equal(abbe_thermal_update_f32(&st, S[0].x, 0x1FFFFu, 0.0f), ABBE_OK); /* first: dt ignored */
    assert_int_equal(abbe_thermal_update_f32(&st, S[1].x, 0x1FFFFu, 0.0f), ABBE_E_ARG);
    assert_int_equal(abbe_thermal_update_f32(&st, S[1].x, 0x1FFFFu, -1.0f), ABBE_E_ARG);
    assert_int_equal(abbe_thermal_state_sizeof(), sizeof(abbe_thermal_state_t));
    assert_int_equal(abbe_thermal_model_sizeof(), sizeof(abbe_thermal_model_t));
    /* NaN reads as out of range */
    float x[17];
    memcpy(x, S[1].x, sizeof x);
    x[2] = 0.0f / 0.0f;
    assert_int_equal(abbe_thermal_update_f32(&st, x, 0x1FFFFu, 10.0f), ABBE_OK);
    assert_int_equal(abbe_thermal_input_faults(&st), 1u << 2);
    assert_true(abbe_thermal_flags(&st) & ABBE_THERMAL_F_RANGE);
}

/* abbe_comp_step_thermal_*: with NULL it is exactly abbe_comp_step_*; with a
 * running thermal state its target is the model's plus the thermal tip error. */
static void test_comp_step_thermal(void **state)
{
    (void)state;
    abbe_model_t m;
    abbe_thermal_model_t th;
    abbe_thermal_state_t ts;
    assert_int_equal(abbe_thermal_load(&m, &th, abbe_golden_thermal_blob, abbe_golden_thermal_blob_size), ABBE_OK);
    abbe_comp_config_t cfg;
    memset(&cfg, 0, sizeof cfg);
    for (unsigned j = 0; j < 3u; j++) {
        cfg.warn_nm[j] = 5000000;
        cfg.limit_nm[j] = 10000000;
        cfg.rate_nm_per_cycle[j] = 10000000;
        cfg.axis_sign[j] = 1;
    }
    cfg.fade_cycles = 1;
    cfg.stale_cycles = 5;
    abbe_comp_t a, b, c;
    assert_int_equal(abbe_comp_init(&a, &cfg, &m), ABBE_OK);
    assert_int_equal(abbe_comp_init(&b, &cfg, &m), ABBE_OK);
    assert_int_equal(abbe_comp_init(&c, &cfg, &m), ABBE_OK);
    abbe_comp_enable(&a);
    abbe_comp_enable(&b);
    abbe_comp_enable(&c);
    assert_int_equal(abbe_thermal_init_q(&ts, &th, 30000000u), ABBE_OK); /* one call = a whole fade */
    for (uint32_t n = 0; n < 20u; n++) {
        assert_int_equal(abbe_thermal_update_q(&ts, S[n].x_milli, 0x1FFFFu, n ? S[n].dt_ms : 0u), ABBE_OK);
        abbe_comp_input_q_t in = {{100000000 + 1000000 * (int32_t)n, -50000000, -20000000}, {20000, 20000, 20000},
                                  {1, 0, 0}, 1, 0};
        abbe_comp_output_t oa, ob, oc;
        assert_int_equal(abbe_comp_step_q(&a, &in, &oa), ABBE_OK);
        assert_int_equal(abbe_comp_step_thermal_q(&b, NULL, &in, &ob), ABBE_OK);
        assert_int_equal(abbe_comp_step_thermal_q(&c, &ts, &in, &oc), ABBE_OK);
        assert_memory_equal(&oa, &ob, sizeof oa);
        for (unsigned j = 0; j < 3u; j++) { /* target = -(model error + thermal tip error) */
            int64_t d = (int64_t)oa.target_nm[j] - oc.target_nm[j] - S[n].tip_q_nm[j];
            assert_true(d <= 2 && d >= -2);
        }
    }
    assert_int_equal(abbe_comp_step_thermal_q(NULL, &ts, NULL, NULL), ABBE_E_ARG);
}

/* apply_ms: the fades and the watchdog advanced by real time. With a whole
 * period per call it equals apply() at that period (bit for bit in _q, the
 * same Q24 fade step); with irregular gaps (0 ms too) the weights move by
 * elapsed / fade_ms per call and a missing sample is flagged after max_gap_ms
 * of elapsed time, not calls. */
static void test_apply_ms(void **state)
{
    (void)state;
    abbe_model_t m;
    abbe_thermal_model_t th;
    abbe_thermal_state_t per, tim, fl;
    assert_int_equal(abbe_thermal_load(&m, &th, abbe_golden_thermal_blob, abbe_golden_thermal_blob_size), ABBE_OK);
    assert_int_equal(abbe_thermal_init_q(&per, &th, 1000000u), ABBE_OK);
    assert_int_equal(abbe_thermal_init_q(&tim, &th, 1u), ABBE_OK); /* period unused with apply_ms */
    assert_int_equal(abbe_thermal_init_f32(&fl, &th, 1.0f), ABBE_OK);
    int32_t ep[3], et[3];
    float ef[3];
    /* 1 s per call, a fault on input 16 from sample 20 to 24, then no sample for 200 s */
    for (uint32_t n = 0; n < 30u; n++) {
        uint32_t mask = (n >= 20u && n < 25u) ? 0x0FFFFu : 0x1FFFFu;
        uint32_t dt = n ? S[n].dt_ms : 0u;
        assert_int_equal(abbe_thermal_update_q(&per, S[n].x_milli, mask, dt), ABBE_OK);
        assert_int_equal(abbe_thermal_update_q(&tim, S[n].x_milli, mask, dt), ABBE_OK);
        for (uint32_t k = 0; k < 40u; k++) {
            memset(ep, 0, sizeof ep);
            memset(et, 0, sizeof et);
            abbe_thermal_apply_q(&per, ep);
            abbe_thermal_apply_ms_q(&tim, et, 1000u);
            assert_memory_equal(ep, et, sizeof ep);
            assert_int_equal(abbe_thermal_flags(&per), abbe_thermal_flags(&tim));
        }
    }
    for (uint32_t k = 0; k < 200u; k++) {
        memset(ep, 0, sizeof ep);
        memset(et, 0, sizeof et);
        abbe_thermal_apply_q(&per, ep);
        abbe_thermal_apply_ms_q(&tim, et, 1000u);
        assert_memory_equal(ep, et, sizeof ep);
    }
    assert_true(abbe_thermal_events(&tim) & ABBE_THERMAL_F_GAP);

    /* irregular: steady first (f32 and q side by side) */
    assert_int_equal(abbe_thermal_init_q(&tim, &th, 1u), ABBE_OK);
    for (uint32_t n = 0; n < 20u; n++) {
        uint32_t dt = n ? S[n].dt_ms : 0u;
        assert_int_equal(abbe_thermal_update_q(&tim, S[n].x_milli, 0x1FFFFu, dt), ABBE_OK);
        assert_int_equal(abbe_thermal_update_f32(&fl, S[n].x, 0x1FFFFu, (float)dt * 0.001f), ABBE_OK);
        memset(et, 0, sizeof et);
        memset(ef, 0, sizeof ef);
        abbe_thermal_apply_ms_q(&tim, et, 40000u); /* > fade: a whole fade at once */
        abbe_thermal_apply_ms_f32(&fl, ef, 40000u);
    }
    assert_int_equal(abbe_thermal_flags(&tim) & ABBE_THERMAL_F_FADING, 0u);
    assert_int_equal(abbe_thermal_flags(&fl) & ABBE_THERMAL_F_FADING, 0u);
    int32_t full[3];
    memcpy(full, et, sizeof full);
    for (unsigned a = 0; a < 3u; a++) {
        assert_true(absdiff(et[a], (int32_t)(ef[a] * 1000.0f)) <= 2 + (full[a] < 0 ? -full[a] : full[a]) / 1000);
    }
    /* the speed input opens: fade out by elapsed time, 0 ms calls change nothing */
    assert_int_equal(abbe_thermal_update_q(&tim, S[20].x_milli, 0x0FFFFu, S[20].dt_ms), ABBE_OK);
    assert_int_equal(abbe_thermal_update_f32(&fl, S[20].x, 0x0FFFFu, (float)S[20].dt_ms * 0.001f), ABBE_OK);
    static const uint32_t gaps[] = {0u, 7u, 0u, 1500u, 13u, 250u, 0u, 4000u, 999u, 2u, 10000u, 3333u, 9000u, 2000u};
    uint32_t t = 0u;
    int32_t prev[3];
    memcpy(prev, full, sizeof prev);
    for (unsigned i = 0; i < sizeof gaps / sizeof gaps[0]; i++) {
        t += gaps[i];
        memset(et, 0, sizeof et);
        memset(ef, 0, sizeof ef);
        abbe_thermal_apply_ms_q(&tim, et, gaps[i]);
        abbe_thermal_apply_ms_f32(&fl, ef, gaps[i]);
        for (unsigned a = 0; a < 3u; a++) {
            int64_t left = t >= 30000u ? 0 : 30000 - (int64_t)t;
            int64_t expect = (int64_t)full[a] * left / 30000;
            int32_t tol = 2 + (full[a] < 0 ? -full[a] : full[a]) / 1000;
            assert_true(absdiff(et[a], (int32_t)expect) <= tol);
            assert_true(absdiff((int32_t)(ef[a] * 1000.0f), (int32_t)expect) <= tol);
            /* no step larger than the fade rate allows for the time that passed */
            int64_t allowed = ((int64_t)(full[a] < 0 ? -full[a] : full[a]) * gaps[i]) / 30000 + 2;
            assert_true(absdiff(et[a], prev[a]) <= allowed);
            if (gaps[i] == 0u) {
                assert_int_equal(et[a], prev[a]);
            }
        }
        memcpy(prev, et, sizeof prev);
    }
    assert_true(t >= 30000u);
    assert_int_equal(et[0], 0);
    assert_true(abbe_thermal_flags(&tim) & ABBE_THERMAL_F_HOLD);
    /* the watchdog counts ms: max_gap is 120 s after the last update */
    assert_int_equal(abbe_thermal_update_q(&tim, S[21].x_milli, 0x1FFFFu, S[21].dt_ms), ABBE_OK);
    assert_int_equal(abbe_thermal_update_f32(&fl, S[21].x, 0x1FFFFu, (float)S[21].dt_ms * 0.001f), ABBE_OK);
    abbe_thermal_clear_events(&tim);
    abbe_thermal_clear_events(&fl);
    for (uint32_t k = 0; k < 1199u; k++) { /* 119.9 s in 100 ms calls */
        abbe_thermal_apply_ms_q(&tim, et, 100u);
        abbe_thermal_apply_ms_f32(&fl, ef, 100u);
    }
    abbe_thermal_apply_ms_q(&tim, et, 100u); /* exactly 120 s: not yet late */
    abbe_thermal_apply_ms_f32(&fl, ef, 100u);
    assert_int_equal(abbe_thermal_events(&tim) & ABBE_THERMAL_F_GAP, 0u);
    assert_int_equal(abbe_thermal_events(&fl) & ABBE_THERMAL_F_GAP, 0u);
    abbe_thermal_apply_ms_q(&tim, et, 1u);
    abbe_thermal_apply_ms_f32(&fl, ef, 1u);
    assert_true(abbe_thermal_flags(&tim) & ABBE_THERMAL_F_GAP);
    assert_true(abbe_thermal_flags(&fl) & ABBE_THERMAL_F_GAP);
    /* a huge elapsed time saturates (no wrap back under max_gap) */
    abbe_thermal_apply_ms_q(&tim, et, 0xFFFFFFFFu);
    abbe_thermal_apply_ms_q(&tim, et, 0xFFFFFFFFu);
    assert_true(abbe_thermal_flags(&tim) & ABBE_THERMAL_F_GAP);
}

/* ---- stuck: an input whose readings stay within the resolution for the stuck time ---- */
#define STUCK_MIN 2u
#define STUCK_RES_MILLI 20u /* 0.02 K */

/* The input FAULT_INPUT over 40 samples 10 s apart: a ramp of 0.1 K per sample
 * (n < 10), then held at the ramp's last value with a +/-0.01 K dither (within
 * the resolution; n 10..29), then the ramp again (n >= 30). */
static float stuck_value(float v0, uint32_t n)
{
    if (n < 10u) return v0 + 0.1f * (float)n;
    if (n < 30u) return v0 + 0.9f + ((n & 1u) ? 0.01f : -0.01f);
    return v0 + 0.9f + 0.1f * (float)(n - 29u);
}

static void run_stuck(int with_check, int use_q)
{
    blob_buf_t buf;
    abbe_model_t m;
    abbe_thermal_model_t th;
    abbe_thermal_state_t st;
    copy_golden(&buf);
    if (with_check) {
        uint8_t *in = buf.b + block_off(&buf) + IN(FAULT_INPUT, 0);
        in[1] = (uint8_t)STUCK_MIN;
        in[2] = (uint8_t)STUCK_RES_MILLI;
        in[3] = 0u;
        fix_crc(buf.b);
    }
    assert_int_equal(load(&buf), ABBE_OK);
    assert_int_equal(abbe_thermal_load(&m, &th, buf.b, abbe_golden_thermal_blob_size), ABBE_OK);
    if (use_q) {
        assert_int_equal(abbe_thermal_init_q(&st, &th, 1000000u), ABBE_OK);
    } else {
        assert_int_equal(abbe_thermal_init_f32(&st, &th, 1.0f), ABBE_OK);
    }
    uint32_t first_stuck = 0u, last_stuck = 0u;
    for (uint32_t n = 0; n < 40u; n++) {
        float x[17];
        memcpy(x, S[0].x, sizeof x);
        x[FAULT_INPUT] = stuck_value(S[0].x[FAULT_INPUT], n);
        if (use_q) {
            int32_t xm[17];
            for (unsigned k = 0; k < 17u; k++) {
                float v = k < 16u ? x[k] * 1000.0f : x[k]; /* m degC; rpm */
                xm[k] = (int32_t)(v < 0.0f ? v - 0.5f : v + 0.5f);
            }
            assert_int_equal(abbe_thermal_update_q(&st, xm, 0x1FFFFu, n ? 10000u : 0u), ABBE_OK);
        } else {
            assert_int_equal(abbe_thermal_update_f32(&st, x, 0x1FFFFu, n ? 10.0f : 0.0f), ABBE_OK);
        }
        uint32_t f = abbe_thermal_flags(&st);
        assert_int_equal(f & (ABBE_THERMAL_F_FAULTS & ~ABBE_THERMAL_F_STUCK), 0u);
        if (f & ABBE_THERMAL_F_STUCK) {
            assert_int_equal(abbe_thermal_input_faults(&st), 1u << FAULT_INPUT);
            assert_true(f & ABBE_THERMAL_F_HOLD);
            first_stuck = first_stuck ? first_stuck : n;
            last_stuck = n;
        }
        for (uint32_t k = 0; k < 10u; k++) {
            float err_f[3];
            int32_t err_q[3];
            if (use_q) abbe_thermal_apply_q(&st, err_q); else abbe_thermal_apply_f32(&st, err_f);
        }
    }
    if (!with_check) {
        assert_int_equal(first_stuck, 0u);
        assert_int_equal(abbe_thermal_events(&st) & ABBE_THERMAL_F_STUCK, 0u);
        return;
    }
    /* anchored at n = 9 (the last ramp value): 120 s still at n = 21, until the ramp
     * moves it again at n = 30 */
    print_message("stuck (%s): flagged from sample %u to %u\n", use_q ? "q" : "f32", first_stuck, last_stuck);
    assert_int_equal(first_stuck, 9u + STUCK_MIN * 6u);
    assert_int_equal(last_stuck, 29u);
    assert_true(abbe_thermal_events(&st) & ABBE_THERMAL_F_STUCK);
}

/* A term without lag (tau 0, which the loader accepts) takes each sample
 * whole: after a step its state is the sample's, exactly as a channel just
 * started on that sample (the weight dt / (0 + dt) = 1, which thermal_q.c
 * gives without the division). */
static void test_tau_zero_q(void **state)
{
    (void)state;
    blob_buf_t buf;
    copy_golden(&buf);
    const uint32_t t = block_off(&buf);
    for (unsigned c = 0; c < 5u; c++) {
        for (unsigned k = 0; k < buf.b[t + CH(c, 1)]; k++) {
            put_u32(buf.b + t + CH(c, 8u + 12u * k + 4u), 0u);
        }
    }
    fix_crc(buf.b);
    abbe_model_t m;
    abbe_thermal_model_t th;
    assert_int_equal(abbe_thermal_load(&m, &th, buf.b, abbe_golden_thermal_blob_size), ABBE_OK);
    abbe_thermal_state_t stepped, started;
    assert_int_equal(abbe_thermal_init_q(&stepped, &th, 1000u), ABBE_OK);
    assert_int_equal(abbe_thermal_init_q(&started, &th, 1000u), ABBE_OK);
    assert_int_equal(abbe_thermal_update_q(&stepped, S[0].x_milli, 0x1FFFFu, 0u), ABBE_OK);
    assert_int_equal(abbe_thermal_update_q(&stepped, S[1].x_milli, 0x1FFFFu, S[1].dt_ms), ABBE_OK);
    assert_int_equal(abbe_thermal_update_q(&started, S[1].x_milli, 0x1FFFFu, 0u), ABBE_OK);
    assert_int_equal(abbe_thermal_flags(&stepped) & (ABBE_THERMAL_F_HOLD | ABBE_THERMAL_F_GAP), 0u);
    int32_t y_stepped[ABBE_THERMAL_MAX_CHANNELS], y_started[ABBE_THERMAL_MAX_CHANNELS];
    assert_int_equal(abbe_thermal_channels_q(&stepped, y_stepped), 5);
    assert_int_equal(abbe_thermal_channels_q(&started, y_started), 5);
    unsigned moved = 0u;
    for (unsigned c = 0; c < 5u; c++) {
        assert_int_equal(y_stepped[c], y_started[c]);
        moved += y_started[c] != 0;
    }
    assert_true(moved > 0u); /* the comparison is not of zeros */
}

/* A tilt channel (A, B) at its limit, 2^30 nrad, on a tool offset t_z beyond
 * 2.1 m (both accepted by the loader): its tool tip share y t_z / 10^9 is
 * beyond int32. It is held to +/-INT32_MAX (and flagged), never wrapped: the
 * int32 conversion wrapped it to the opposite sign before (found by the proof
 * thermal_any_q, docs/proofs.md). Only the tilt channels have a gain here,
 * every input far above its reference, no lag, a fade of 1 ms. */
static void tilt_tip_err(int32_t tool_z_nm, int32_t err[3], uint32_t *flags)
{
    blob_buf_t buf;
    copy_golden(&buf);
    const uint32_t t = block_off(&buf);
    put_u32(buf.b + 20, get_u32(buf.b + 20) | ABBE_FEATURE_TOOL_OFFSET);
    put_u32(buf.b + 36 + 8, (uint32_t)tool_z_nm);
    put_u32(buf.b + t + 8u, 1u); /* fade 1 ms */
    for (unsigned k = 0; k < 17u; k++) {
        put_u32(buf.b + t + IN(k, 4u), 0u);                 /* reference 0 */
        put_u32(buf.b + t + IN(k, 8u), (uint32_t)-(1 << 20)); /* valid range: the caps */
        put_u32(buf.b + t + IN(k, 12u), 1u << 20);
        put_u32(buf.b + t + IN(k, 16u), 1u << 21);          /* max step */
    }
    for (unsigned c = 0; c < 5u; c++) {
        const unsigned tilt = buf.b[t + CH(c, 0)] >= ABBE_THERMAL_OUT_A;
        put_u32(buf.b + t + CH(c, 4u), 1u << 30); /* limit */
        for (unsigned k = 0; k < buf.b[t + CH(c, 1)]; k++) {
            put_u32(buf.b + t + CH(c, 8u + 12u * k + 4u), 0u); /* tau 0 */
            put_u32(buf.b + t + CH(c, 8u + 12u * k + 8u), tilt ? 1u << 28 : 0u);
        }
    }
    fix_crc(buf.b);
    abbe_model_t m;
    abbe_thermal_model_t th;
    assert_int_equal(abbe_thermal_load(&m, &th, buf.b, abbe_golden_thermal_blob_size), ABBE_OK);
    abbe_thermal_state_t st;
    assert_int_equal(abbe_thermal_init_q(&st, &th, 1000u), ABBE_OK);
    int32_t x[17];
    for (unsigned k = 0; k < 17u; k++) {
        x[k] = 1 << 20; /* 1048 K (or rpm) above the reference */
    }
    assert_int_equal(abbe_thermal_update_q(&st, x, 0x1FFFFu, 0u), ABBE_OK);
    for (unsigned n = 0; n < 3u; n++) { /* faded in */
        memset(err, 0, 3u * sizeof err[0]);
        abbe_thermal_apply_q(&st, err);
    }
    *flags = abbe_thermal_flags(&st);
}

static void test_tilt_tip_saturates_q(void **state)
{
    (void)state;
    int32_t fits[3], beyond[3];
    uint32_t flags_fits, flags_beyond;
    tilt_tip_err(-(1 << 30), fits, &flags_fits);            /* 2^30 x 2^30 / 10^9: fits int32 */
    tilt_tip_err(INT32_MIN + 1, beyond, &flags_beyond);     /* 2^30 x (2^31 - 1) / 10^9: does not */
    unsigned nonzero = 0;
    for (unsigned j = 0; j < 3u; j++) {
        /* the same sign, at least as large: no wrap */
        assert_true((int64_t)fits[j] * beyond[j] >= 0);
        assert_true(beyond[j] >= 0 ? beyond[j] >= fits[j] : beyond[j] <= fits[j]);
        nonzero += beyond[j] != 0;
    }
    assert_true(nonzero > 0u);
    assert_true(flags_beyond & ABBE_THERMAL_F_LIMIT);
}

static void test_stuck(void **state)
{
    (void)state;
    run_stuck(1, 0);
    run_stuck(1, 1);
    run_stuck(0, 0);
    run_stuck(0, 1);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_loaders),     cmocka_unit_test(test_every_status),
        cmocka_unit_test(test_golden_f32),  cmocka_unit_test(test_golden_q),
        cmocka_unit_test(test_faults_f32),  cmocka_unit_test(test_fade_rate_q),
        cmocka_unit_test(test_args),
        cmocka_unit_test(test_comp_step_thermal),
        cmocka_unit_test(test_apply_ms),
        cmocka_unit_test(test_tau_zero_q),
        cmocka_unit_test(test_stuck),
        cmocka_unit_test(test_tilt_tip_saturates_q),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}

/* abbe: abbe_thermal_load(), the loader of format 1.3 tables (abbe/thermal.h).
 *
 * model_load.c compiled a third time with ABBE_MODEL_LOAD_THERMAL: the checks
 * of the header and the linear axes are the same source (minor 3 and the
 * THERMAL_DYN bit read, the header's reserved word the block's offset), then
 * the thermal block's checks (docs/table-format.md, "Thermal block", in that
 * order). abbe_model_load's translation unit is untouched: a firmware that
 * does not call abbe_thermal_load pays no flash for it, and abbe_model_load
 * refuses a 1.3 table by its minor, as every older reader does. */
#if !defined(ABBE_NO_REVERSAL)
#include "abbe/thermal.h"
#define ABBE_MODEL_LOAD_THERMAL 1
#include "model_load.c" /* NOLINT(bugprone-suspicious-include): the same source compiled a third time, on purpose */

#define TH_HEADER_SIZE 16u
#define TH_INPUT_SIZE 20u
#define TH_CHANNEL_SIZE 56u
#define TH_TERM_SIZE 12u
#define TH_VALUE_CAP ((int32_t)1 << 20)      /* |reference|, |valid_min|, |valid_max|, milli-units */
#define TH_STEP_CAP ((int32_t)1 << 21)       /* max_step */
#define TH_LIMIT_CAP ((int32_t)1 << 30)      /* channel limit, nm / nrad */
#define TH_GAIN_CAP ((int32_t)1 << 28)       /* |gain|, 2^-16 um per unit */
#define TH_TIME_CAP ((uint32_t)1 << 31)      /* tau, max_gap, fade, ms */

#include "thermal_acsl.h" /* the contracts of the functions below, for WP (ACSL only) */

/* Byte offsets (in the table) of the block's records: t the block's offset. */
static uint32_t th_input(uint32_t t, unsigned k)
{
    return t + TH_HEADER_SIZE + TH_INPUT_SIZE * k;
}

static uint32_t th_channel(uint32_t t, unsigned n_inputs, unsigned c)
{
    return t + TH_HEADER_SIZE + TH_INPUT_SIZE * n_inputs + TH_CHANNEL_SIZE * c;
}

static uint32_t th_term(uint32_t ch, unsigned k)
{
    return ch + 8u + TH_TERM_SIZE * k;
}

/* The block's reads, bounded by the table's CRC word (the value, or 0 past it).
 * check_thermal places the whole block inside [DATA_START, total - 4) before
 * it reads anything at an offset derived from the block's counts, so the
 * bound never binds on a table that gets there; it makes each read's bound
 * evident at the read, where the proof (tests/proofs/load_thermal.c) checks it
 * without relating the block's offset and counts to total (as coef_word). */
static unsigned th_u8(const uint8_t *b, uint32_t total, uint32_t at)
{
    return total >= 5u && at < total - 4u ? b[at] : 0u;
}

static unsigned th_u16(const uint8_t *b, uint32_t total, uint32_t at)
{
    return total >= 6u && at <= total - 6u ? abbe_ld_u16(b + at) : 0u;
}

static uint32_t th_u32(const uint8_t *b, uint32_t total, uint32_t at)
{
    return total >= 8u && at <= total - 8u ? abbe_ld_u32(b + at) : 0u;
}

static int32_t th_i32(const uint8_t *b, uint32_t total, uint32_t at)
{
    return total >= 8u && at <= total - 8u ? abbe_ld_i32(b + at) : 0;
}

static int th_abs_over(int32_t v, int32_t cap)
{
    return v > cap || v < -cap;
}

/* The thermal block's checks, after every check of the table (order: OFFSET of
 * its header, COUNT of inputs and channels, OFFSET of the whole block, FLAGS,
 * COUNT of terms, RANGE). */
static abbe_status_t check_thermal(const uint8_t *b, uint32_t total)
{
    uint32_t t = abbe_ld_u32(b + H_RESERVED);
    if ((t & 3u) != 0u || t < DATA_START || t > total - 4u || total - 4u - t < TH_HEADER_SIZE) {
        return ABBE_E_OFFSET;
    }
    unsigned n_in = th_u8(b, total, t), n_ch = th_u8(b, total, t + 1u);
    if (n_in < 1u || n_in > ABBE_THERMAL_MAX_INPUTS || n_ch < 1u || n_ch > ABBE_THERMAL_MAX_CHANNELS) {
        return ABBE_E_COUNT;
    }
    if (total - 4u - t < TH_HEADER_SIZE + TH_INPUT_SIZE * n_in + TH_CHANNEL_SIZE * n_ch) {
        return ABBE_E_OFFSET;
    }
    /*@ TH_ASSERT_FITS */
    /* FLAGS: reserved bytes, kinds, outputs (each at most once), unused term slots */
    if (th_u16(b, total, t + 2u) != 0u || th_u32(b, total, t + 12u) != 0u) {
        return ABBE_E_FLAGS;
    }
    /*@ TH_LOOP_IN_FLAGS */
    for (unsigned k = 0; k < n_in; k++) {
        uint32_t in = th_input(t, k);
        /* in+1: stuck time in minutes (0: no stuck check), in+2..3: stuck
         * resolution in milli-units, 0 without a stuck time */
        if (th_u8(b, total, in) > ABBE_THERMAL_SPEED ||
            (th_u8(b, total, in + 1u) == 0u && th_u16(b, total, in + 2u) != 0u)) {
            return ABBE_E_FLAGS;
        }
    }
    unsigned outputs = 0;
    /*@ TH_LOOP_CH_FLAGS */
    for (unsigned c = 0; c < n_ch; c++) {
        uint32_t ch = th_channel(t, n_in, c);
        unsigned out = th_u8(b, total, ch), n_terms = th_u8(b, total, ch + 1u);
        if (out > ABBE_THERMAL_OUT_B || (outputs & (1u << out)) != 0u || th_u16(b, total, ch + 2u) != 0u) {
            return ABBE_E_FLAGS;
        }
        outputs |= 1u << out;
        /*@ TH_LOOP_SLOTS */
        for (unsigned k = 0; k < ABBE_THERMAL_MAX_TERMS; k++) {
            uint32_t tm = th_term(ch, k);
            unsigned reserved = th_u8(b, total, tm + 1u) | th_u8(b, total, tm + 2u) | th_u8(b, total, tm + 3u);
            if (reserved != 0u || (k >= n_terms && (th_u8(b, total, tm) != 0u || th_u32(b, total, tm + 4u) != 0u ||
                                                    th_u32(b, total, tm + 8u) != 0u))) {
                return ABBE_E_FLAGS;
            }
        }
    }
    /* COUNT: terms per channel, the inputs they read */
    /*@ TH_LOOP_CH_COUNT */
    for (unsigned c = 0; c < n_ch; c++) {
        uint32_t ch = th_channel(t, n_in, c);
        unsigned n_terms = th_u8(b, total, ch + 1u);
        if (n_terms < 1u || n_terms > ABBE_THERMAL_MAX_TERMS) {
            return ABBE_E_COUNT;
        }
        /*@ TH_LOOP_TERM_INPUT */
        for (unsigned k = 0; k < n_terms; k++) {
            if (th_u8(b, total, th_term(ch, k)) >= n_in) {
                return ABBE_E_COUNT;
            }
        }
    }
    /* RANGE */
    uint32_t gap = th_u32(b, total, t + 4u), fade = th_u32(b, total, t + 8u);
    if (gap < 1u || gap > TH_TIME_CAP || fade < 1u || fade > TH_TIME_CAP) {
        return ABBE_E_RANGE;
    }
    /*@ TH_ASSERT_TIMES */
    /*@ TH_LOOP_IN_RANGE */
    for (unsigned k = 0; k < n_in; k++) {
        uint32_t in = th_input(t, k);
        int32_t ref = th_i32(b, total, in + 4u), lo = th_i32(b, total, in + 8u), hi = th_i32(b, total, in + 12u);
        int32_t step = th_i32(b, total, in + 16u);
        if (th_abs_over(ref, TH_VALUE_CAP) || th_abs_over(lo, TH_VALUE_CAP) || th_abs_over(hi, TH_VALUE_CAP) ||
            lo >= hi || step < 1 || step > TH_STEP_CAP) {
            return ABBE_E_RANGE;
        }
    }
    /*@ TH_LOOP_CH_RANGE */
    for (unsigned c = 0; c < n_ch; c++) {
        uint32_t ch = th_channel(t, n_in, c);
        int32_t limit = th_i32(b, total, ch + 4u);
        if (limit < 1 || limit > TH_LIMIT_CAP) {
            return ABBE_E_RANGE;
        }
        unsigned n_terms = th_u8(b, total, ch + 1u);
        /*@ TH_ASSERT_COUNTED */
        /*@ TH_LOOP_TERM_RANGE */
        for (unsigned k = 0; k < n_terms; k++) {
            uint32_t tm = th_term(ch, k);
            if (th_u32(b, total, tm + 4u) > TH_TIME_CAP || th_abs_over(th_i32(b, total, tm + 8u), TH_GAIN_CAP)) {
                return ABBE_E_RANGE;
            }
        }
    }
    return ABBE_OK;
}

/* v, or cap past it: check_thermal has refused every count above its cap, so
 * this never binds; it states the bound where the counts index the model's
 * arrays, for the proof (as the counts are re-read from the table here). */
static unsigned th_cap(unsigned v, unsigned cap)
{
    return v <= cap ? v : cap;
}

static void build_thermal(abbe_thermal_model_t *th, const uint8_t *b, uint32_t total)
{
    memset(th, 0, sizeof *th);
    uint32_t features = abbe_ld_u32(b + H_FEATURES);
    th->tool_z_nm = (features & ABBE_FEATURE_TOOL_OFFSET) != 0u ? abbe_ld_i32(b + H_TOOL + 8u) : 0;
    if ((features & ABBE_FEATURE_THERMAL_DYN) == 0u) {
        return; /* no block: n_inputs = n_channels = 0 */
    }
    uint32_t t = abbe_ld_u32(b + H_RESERVED);
    unsigned n_in = th_cap(th_u8(b, total, t), ABBE_THERMAL_MAX_INPUTS);
    unsigned n_ch = th_cap(th_u8(b, total, t + 1u), ABBE_THERMAL_MAX_CHANNELS);
    /*@ TH_ASSERT_FITS */
    th->n_inputs = (uint8_t)n_in;
    th->n_channels = (uint8_t)n_ch;
    th->max_gap_ms = th_u32(b, total, t + 4u);
    th->fade_ms = th_u32(b, total, t + 8u);
    /*@ TH_LOOP_BUILD_INPUTS */
    for (unsigned k = 0; k < n_in; k++) {
        uint32_t in = th_input(t, k);
        th->kind[k] = (uint8_t)th_u8(b, total, in);
        th->ref_milli[k] = th_i32(b, total, in + 4u);
        th->vmin_milli[k] = th_i32(b, total, in + 8u);
        th->vmax_milli[k] = th_i32(b, total, in + 12u);
        th->max_step_milli[k] = th_i32(b, total, in + 16u);
        th->stuck_ms[k] = (uint32_t)th_u8(b, total, in + 1u) * 60000u;
        th->stuck_res_milli[k] = (int32_t)th_u16(b, total, in + 2u);
    }
    /*@ TH_LOOP_BUILD_CHANNELS */
    for (unsigned c = 0; c < n_ch; c++) {
        uint32_t ch = th_channel(t, n_in, c);
        unsigned n_terms = th_cap(th_u8(b, total, ch + 1u), ABBE_THERMAL_MAX_TERMS);
        th->output[c] = (uint8_t)th_u8(b, total, ch);
        th->n_terms[c] = (uint8_t)n_terms;
        th->limit[c] = th_i32(b, total, ch + 4u);
        /*@ TH_LOOP_BUILD_TERMS */
        for (unsigned k = 0; k < n_terms; k++) {
            uint32_t tm = th_term(ch, k);
            unsigned input = th_cap(th_u8(b, total, tm), ABBE_THERMAL_MAX_INPUTS - 1u); /* < n_in: check_thermal */
            th->term_input[c][k] = (uint8_t)input;
            th->channel_inputs[c] |= 1u << input;
            th->tau_ms[c][k] = th_u32(b, total, tm + 4u);
            th->gain_q16[c][k] = th_i32(b, total, tm + 8u);
        }
    }
#if ABBE_WITH_F32
    /* the float twins: temperatures in degC (milli / 1000), speed in rpm */
    /*@ TH_LOOP_TWINS_INPUTS */
    for (unsigned k = 0; k < n_in; k++) {
        float unit = th->kind[k] == ABBE_THERMAL_SPEED ? 1.0f : 0.001f;
        th->ref[k] = (float)th->ref_milli[k] * unit;
        th->vmin[k] = (float)th->vmin_milli[k] * unit;
        th->vmax[k] = (float)th->vmax_milli[k] * unit;
        th->max_step[k] = (float)th->max_step_milli[k] * unit;
        th->stuck_s[k] = (float)th_u8(b, total, th_input(t, k) + 1u) * 60.0f; /* whole minutes: exact, as the _q path */
        th->stuck_res[k] = (float)th->stuck_res_milli[k] * unit;
        th->rise_scale[k] = th->kind[k] == ABBE_THERMAL_SPEED ? 0.001f : 1.0f;
    }
    /*@ TH_LOOP_TWINS_CHANNELS */
    for (unsigned c = 0; c < n_ch; c++) {
        th->limit_f[c] = (float)th->limit[c] * 0.001f;
        /*@ TH_LOOP_TWINS_TERMS */
        for (unsigned k = 0; k < th->n_terms[c]; k++) {
            th->tau_s[c][k] = (float)th->tau_ms[c][k] * 0.001f;
            th->gain[c][k] = (float)th->gain_q16[c][k] * (1.0f / 65536.0f);
        }
    }
    th->max_gap_s = (float)th->max_gap_ms * 0.001f;
    th->tool_z_mm = (float)th->tool_z_nm * 1e-6f;
#endif
}

abbe_status_t abbe_thermal_load(abbe_model_t *model, abbe_thermal_model_t *thermal, const void *blob, size_t size)
{
    if (model == NULL || thermal == NULL || blob == NULL) {
        return ABBE_E_ARG;
    }
    if (((uintptr_t)blob & 3u) != 0u) {
        return ABBE_E_ALIGN;
    }
    const uint8_t *b = (const uint8_t *)blob;
    uint32_t total = 0;
    abbe_status_t st;
    CHECK_TABLE(st, b, size, total, 0u);
    if (st == ABBE_OK && (abbe_ld_u32(b + H_FEATURES) & ABBE_FEATURE_THERMAL_DYN) != 0u) {
        st = check_thermal(b, total);
    }
    if (st != ABBE_OK) {
        return st; /* both untouched */
    }
    build_model(model, b, total);
    build_thermal(thermal, b, total);
    return ABBE_OK;
}

unsigned abbe_thermal_n_inputs(const abbe_thermal_model_t *thermal)
{
    return thermal != NULL ? thermal->n_inputs : 0u;
}

unsigned abbe_thermal_n_channels(const abbe_thermal_model_t *thermal)
{
    return thermal != NULL ? thermal->n_channels : 0u;
}

size_t abbe_thermal_model_sizeof(void)
{
    return sizeof(abbe_thermal_model_t);
}
#else
typedef int abbe_thermal_load_not_built; /* a format 1.0 library reads no 1.3 tables */
#endif

/* abbe: table validation and the in-place model view (docs/table-format.md).
 *
 * Checks run by category in the order of the spec, each over all axes, so a
 * table with several defects reports the same status here and in the Python
 * reader. Nothing is written to *model until every check has passed.
 */
#include "internal.h"

#define HEADER_SIZE 64u
#define AXIS_RECORD_SIZE 64u
#define DATA_START (HEADER_SIZE + ABBE_AXES * AXIS_RECORD_SIZE)
#define MIN_TOTAL_SIZE (DATA_START + 4u)

/* Header field offsets. */
#define H_MAGIC 0u
#define H_MAJOR 4u
#define H_MINOR 6u
#define H_TOTAL 8u
#define H_HEADER_SIZE 12u
#define H_AXIS_SIZE 16u
#define H_FEATURES 20u
#define H_REFERENCE 24u
#define H_TOOL 36u
#define H_SQUARENESS 48u
#define H_RESERVED 60u

/* Axis record field offsets. */
#define A_MIN 0u
#define A_MAX 4u
#define A_MASK 8u
#define A_DEGREE 9u
#define A_HARMONICS 10u
#define A_PERIOD 12u
#define A_ORIGIN 20u
#define A_BACKLASH 28u
#define A_TAKEUP 32u
#define A_EXPANSION 36u
#define A_THERMAL_OFFSET 40u
#define A_TREF 44u
#define A_COEF_Q 48u
#define A_COEF_F32 52u
#define A_COEF_COUNT 56u
#define A_REVERSAL_ROWS 60u /* format 1.1: u8 rows of the reversal block; bytes 61..63 reserved */

#define LIN_L1_CAP ((uint64_t)1 << 32)
#define ANG_L1_CAP ((uint64_t)1 << 28)
#define SQUARENESS_CAP ((int32_t)1 << 28)
#define REVERSAL_L1_CAP 0x80000000u /* |B| + sum |r_k|: the total reversal stays within 8.39 mm */
#define FEATURES_1_0 0xFu            /* the feature bits of format 1.0 */

/* Rows of an axis' reversal block (format 1.1); a library built without the
 * blocks reads format 1.0 only, where they are 0 (ABBE_NO_REVERSAL). */
#if defined(ABBE_NO_REVERSAL)
#define REVERSAL_ROWS(rec) 0u
#else
#define REVERSAL_ROWS(rec) ((unsigned)(rec)[A_REVERSAL_ROWS])
#endif

static unsigned popcount6(unsigned mask)
{
    unsigned n = 0;
    for (unsigned t = 0; t < ABBE_TERMS; t++) {
        n += (mask >> t) & 1u;
    }
    return n;
}

static unsigned trend_rows_of(uint8_t degree)
{
    return degree == ABBE_NO_TREND ? 0u : (unsigned)degree + 1u;
}

ABBE_NOINLINE static uint32_t n_basis_of(const uint8_t *rec)
{
    return trend_rows_of(rec[A_DEGREE]) + 2u * rec[A_HARMONICS] + 2u * rec[A_HARMONICS + 1u];
}

static uint32_t n_matrix_of(const uint8_t *rec)
{
    return n_basis_of(rec) * popcount6(rec[A_MASK]);
}

/* rotary: ABBE_FEATURE_ROTARY for the five-axis loader (minor 2 read; a table
 * with the rotary section has room for it), else 0. */
/* Contract proven by WP (scripts/prove.sh --wp, docs/proofs.md): an accepted
 * header gives a total size the buffer holds, a multiple of 4, at least the
 * header, the three axis records and the CRC word. */
/*@ requires valid_header: size >= HEADER_SIZE ==> \valid_read(b + (0 .. HEADER_SIZE - 1));
    requires valid_table: \valid_read(b + (0 .. size - 1));
    requires out: \valid(total_out);
    assigns *total_out;
    ensures accepted_total: \result == ABBE_OK ==>
        MIN_TOTAL_SIZE <= *total_out <= size && *total_out % 4 == 0;
 */
static abbe_status_t check_header(const uint8_t *b, size_t size, uint32_t *total_out, uint32_t rotary)
{
    if (size < HEADER_SIZE) {
        return ABBE_E_TRUNCATED;
    }
    uint32_t total = abbe_ld_u32(b + H_TOTAL);
    if (size < total) {
        return ABBE_E_TRUNCATED;
    }
    if (memcmp(b + H_MAGIC, "ABBE", 4) != 0) {
        return ABBE_E_MAGIC;
    }
    if (abbe_ld_u16(b + H_MAJOR) != ABBE_TABLE_FORMAT_MAJOR) {
        return ABBE_E_VERSION_MAJOR;
    }
#if defined(ABBE_MODEL_LOAD_THERMAL) /* thermal_load.c: format 1.3 (thermal block) read, no rotary section */
    if (abbe_ld_u16(b + H_MINOR) > ABBE_THERMAL_FORMAT_MINOR) {
#else
#if defined(ABBE_NO_FIVE_KINDS)
    if (abbe_ld_u16(b + H_MINOR) > (rotary != 0u ? ABBE_FIVE_FORMAT_MINOR : ABBE_TABLE_FORMAT_MINOR)) {
#else /* 1.3 is the thermal block's (a 3-axis table's): refused here, 1.4 read */
    if (abbe_ld_u16(b + H_MINOR) > (rotary != 0u ? ABBE_FIVE_FORMAT_MINOR : ABBE_TABLE_FORMAT_MINOR) ||
        (rotary != 0u && abbe_ld_u16(b + H_MINOR) == 3u)) {
#endif
#endif
        return ABBE_E_VERSION_MINOR;
    }
    if (abbe_ld_u32(b + H_HEADER_SIZE) != HEADER_SIZE ||
        abbe_ld_u32(b + H_AXIS_SIZE) != AXIS_RECORD_SIZE || total < MIN_TOTAL_SIZE ||
        (total % 4u) != 0u ||
        ((abbe_ld_u32(b + H_FEATURES) & rotary) != 0u && total < ABBE_ROTARY_DATA_START + 4u)) {
        return ABBE_E_SIZE;
    }
    if (abbe_crc32(0, b, total - 4u) != abbe_ld_u32(b + total - 4u)) {
        return ABBE_E_CRC;
    }
    *total_out = total;
    return ABBE_OK;
}

/* Out of line here and below: the loader runs once, and the copies GCC
 * would inline cost flash the evaluation needs. */
ABBE_NOINLINE static int any_nonzero_i32(const uint8_t *p, unsigned count)
{
    for (unsigned i = 0; i < count; i++) {
        if (abbe_ld_u32(p + 4u * i) != 0u) {
            return 1;
        }
    }
    return 0;
}

static abbe_status_t check_flags(const uint8_t *b, uint32_t rotary)
{
    uint32_t features = abbe_ld_u32(b + H_FEATURES);
#if defined(ABBE_NO_REVERSAL)
    (void)rotary; /* such a library reads 1.0 only */
    if ((features & ~FEATURES_1_0) != 0u || abbe_ld_u32(b + H_RESERVED) != 0u) {
        return ABBE_E_FLAGS;
    }
#else
    /* a 1.0 table knows no REVERSAL bit; REVERSAL uses BACKLASH's take-up and direction state */
    uint32_t known = ABBE_FEATURE_ALL >> (abbe_ld_u16(b + H_MINOR) == 0u); /* 1.0: FEATURES_1_0 */
    known |= abbe_ld_u16(b + H_MINOR) >= 2u ? rotary : 0u;                 /* 1.2: ROTARY (five_load.c) */
#if defined(ABBE_MODEL_LOAD_THERMAL)
    /* 1.3: THERMAL_DYN; the header's reserved word is then the thermal block's offset */
    known |= abbe_ld_u16(b + H_MINOR) >= 3u ? ABBE_FEATURE_THERMAL_DYN : 0u;
#define H_RESERVED_WORD(b) ((abbe_ld_u32((b) + H_FEATURES) & ABBE_FEATURE_THERMAL_DYN) != 0u ? 0u : abbe_ld_u32((b) + H_RESERVED))
#else
#define H_RESERVED_WORD(b) abbe_ld_u32((b) + H_RESERVED)
#endif
    if ((features & ~known) != 0u || H_RESERVED_WORD(b) != 0u ||
        (features & (ABBE_FEATURE_REVERSAL | ABBE_FEATURE_BACKLASH)) == ABBE_FEATURE_REVERSAL) {
        return ABBE_E_FLAGS;
    }
#endif
    if (!(features & ABBE_FEATURE_TOOL_OFFSET) && any_nonzero_i32(b + H_TOOL, 3)) {
        return ABBE_E_FLAGS;
    }
    if (!(features & ABBE_FEATURE_SQUARENESS) && any_nonzero_i32(b + H_SQUARENESS, 3)) {
        return ABBE_E_FLAGS;
    }
    for (unsigned j = 0; j < ABBE_AXES; j++) {
        const uint8_t *rec = b + HEADER_SIZE + j * AXIS_RECORD_SIZE;
        /* reserved bytes 61..63, and the reversal rows (byte 60, reserved in 1.0) without REVERSAL */
        uint32_t word = abbe_ld_u32(rec + A_REVERSAL_ROWS);
#if !defined(ABBE_NO_REVERSAL)
        word >>= (features & ABBE_FEATURE_REVERSAL) >> 1; /* REVERSAL: bytes 61..63 only */
#endif
        if (word != 0u) {
            return ABBE_E_FLAGS;
        }
        if (!(features & ABBE_FEATURE_BACKLASH) && any_nonzero_i32(rec + A_BACKLASH, 2)) {
            return ABBE_E_FLAGS;
        }
        if (!(features & ABBE_FEATURE_THERMAL) && any_nonzero_i32(rec + A_EXPANSION, 3)) {
            return ABBE_E_FLAGS;
        }
    }
    return ABBE_OK;
}

static abbe_status_t check_counts(const uint8_t *b)
{
    for (unsigned j = 0; j < ABBE_AXES; j++) {
        const uint8_t *rec = b + HEADER_SIZE + j * AXIS_RECORD_SIZE;
        uint8_t degree = rec[A_DEGREE];
        if ((rec[A_MASK] & 0xC0u) != 0u ||
            (degree > ABBE_MAX_DEGREE && degree != ABBE_NO_TREND) ||
            rec[A_HARMONICS] > ABBE_MAX_HARMONICS || rec[A_HARMONICS + 1u] > ABBE_MAX_HARMONICS ||
            REVERSAL_ROWS(rec) > ABBE_MAX_REVERSAL_ROWS) {
            return ABBE_E_COUNT;
        }
        if (abbe_ld_u32(rec + A_COEF_COUNT) != n_matrix_of(rec) + REVERSAL_ROWS(rec)) {
            return ABBE_E_COUNT;
        }
    }
    return ABBE_OK;
}

/* Contract proven by WP (docs/proofs.md): an accepted array of count words
 * at offset lies in [data_start, total - 4), 4-byte aligned. */
/*@ requires total_has_crc: total >= 4;
    assigns \nothing;
    ensures inside: \result != 0 ==>
        data_start <= offset && offset % 4 == 0 && offset + 4 * count <= total - 4;
 */
static int array_ok(uint32_t offset, uint32_t count, uint32_t total, uint32_t data_start)
{
    uint64_t end = (uint64_t)offset + 4u * (uint64_t)count;
    return offset >= data_start && (offset % 4u) == 0u && end <= (uint64_t)total - 4u;
}

static abbe_status_t check_offsets(const uint8_t *b, uint32_t total, uint32_t data_start)
{
    for (unsigned j = 0; j < ABBE_AXES; j++) {
        const uint8_t *rec = b + HEADER_SIZE + j * AXIS_RECORD_SIZE;
        uint32_t count = abbe_ld_u32(rec + A_COEF_COUNT);
        uint32_t off_q = abbe_ld_u32(rec + A_COEF_Q);
        uint32_t off_f = abbe_ld_u32(rec + A_COEF_F32);
        if (count == 0u) {
            if (off_q != 0u || off_f != 0u) {
                return ABBE_E_OFFSET;
            }
        } else if (!array_ok(off_q, count, total, data_start) || !array_ok(off_f, count, total, data_start)) {
            return ABBE_E_OFFSET;
        }
    }
    return ABBE_OK;
}

/* Word i of the coefficient array at byte offset off of a table of total
 * bytes. check_offsets() has placed every array inside [data start, total - 4)
 * before any check reads one, so the bound never binds on a table that gets
 * here; it makes each read's bound evident at the read, where the proof
 * (docs/proofs.md) checks it without relating offsets and counts read from
 * the table at different places. */
static uint32_t coef_word(const uint8_t *b, uint32_t total, uint32_t off, uint32_t i)
{
    uint32_t at = off + 4u * i; /* mod 2^32 */
    return total >= 8u && at <= total - 8u ? abbe_ld_u32(b + at) : 0u; /* total >= MIN_TOTAL_SIZE */
}

static abbe_status_t check_finite(const uint8_t *b, uint32_t total)
{
    for (unsigned j = 0; j < ABBE_AXES; j++) {
        const uint8_t *rec = b + HEADER_SIZE + j * AXIS_RECORD_SIZE;
        uint32_t count = abbe_ld_u32(rec + A_COEF_COUNT);
        uint32_t off_f = abbe_ld_u32(rec + A_COEF_F32);
        for (uint32_t i = 0; i < count; i++) {
            if (abbe_f32_bits_nonfinite(coef_word(b, total, off_f, i))) {
                return ABBE_E_NONFINITE;
            }
        }
    }
    return ABBE_OK;
}

/* IEEE single-precision bits of v, rounded to nearest even. A Cortex-M4F
 * converts in hardware (VCVT, in the FPU's default round-to-nearest mode,
 * which the _f32 evaluation assumes too: docs/numerics.md); elsewhere in
 * integers only, since the loader serves the float-free fixed-point build
 * too. */
#if defined(__GNUC__) && defined(__thumb2__) && defined(__ARM_FP) && (__ARM_FP & 4) && !defined(ABBE_PORTABLE_C)
static uint32_t i32_to_f32_bits(int32_t v)
{
    const float f = (float)v;
    uint32_t bits;
    memcpy(&bits, &f, sizeof bits);
    return bits;
}
#else
static unsigned bit_length(uint32_t v);

static uint32_t i32_to_f32_bits(int32_t v)
{
    /*@ split v < 0; */ /* Eva: the two signs apart, so v != 0 below is an interval */
    if (v == 0) {
        return 0u;
    }
    const uint32_t sign = v < 0 ? 0x80000000u : 0u;
    const uint32_t mag = v < 0 ? 0u - (uint32_t)v : (uint32_t)v; /* 2^31 for INT32_MIN */
    const unsigned n = bit_length(mag);                           /* 1..32 significant bits */
    uint32_t mant;                                                /* 24 bits, 2^23 <= mant <= 2^24 */
    if (n <= 24u) {
        mant = mag << (24u - n);
    } else {
        /* round to nearest, ties to even: add half - 1, plus 1 if the kept
         * part is odd (mag + 2^7 stays below 2^32) */
        const unsigned shift = n - 24u;
        mant = (mag + ((1u << (shift - 1u)) - 1u) + ((mag >> shift) & 1u)) >> shift;
    }
    /* a mantissa rounded up to 2^24 carries into the exponent by itself */
    return sign | (((uint32_t)(126u + n) << 23) + (mant - 0x00800000u));
}
#endif

/* The float32 array must be the int32 array converted: checked bit for bit, so
 * both variants evaluate the same table whatever wrote it. */
static abbe_status_t check_twins(const uint8_t *b, uint32_t total)
{
    for (unsigned j = 0; j < ABBE_AXES; j++) {
        const uint8_t *rec = b + HEADER_SIZE + j * AXIS_RECORD_SIZE;
        uint32_t count = abbe_ld_u32(rec + A_COEF_COUNT);
        uint32_t off_q = abbe_ld_u32(rec + A_COEF_Q);
        uint32_t off_f = abbe_ld_u32(rec + A_COEF_F32);
        for (uint32_t i = 0; i < count; i++) {
            if (coef_word(b, total, off_f, i) != i32_to_f32_bits(abbe_u32_to_i32(coef_word(b, total, off_q, i)))) {
                return ABBE_E_MISMATCH;
            }
        }
    }
    return ABBE_OK;
}

static abbe_status_t check_periods(const uint8_t *b)
{
    for (unsigned j = 0; j < ABBE_AXES; j++) {
        const uint8_t *rec = b + HEADER_SIZE + j * AXIS_RECORD_SIZE;
        for (unsigned k = 0; k < ABBE_BLOCKS; k++) {
            int32_t period = abbe_ld_i32(rec + A_PERIOD + 4u * k);
            int32_t origin = abbe_ld_i32(rec + A_ORIGIN + 4u * k);
            if (rec[A_HARMONICS + k] > 0u ? period <= 0 : (period != 0 || origin != 0)) {
                return ABBE_E_PERIOD;
            }
        }
    }
    return ABBE_OK;
}

static abbe_status_t check_travel(const uint8_t *b)
{
    for (unsigned j = 0; j < ABBE_AXES; j++) {
        const uint8_t *rec = b + HEADER_SIZE + j * AXIS_RECORD_SIZE;
        if (abbe_ld_i32(rec + A_MIN) >= abbe_ld_i32(rec + A_MAX)) {
            return ABBE_E_TRAVEL;
        }
    }
    return ABBE_OK;
}

#if !defined(ABBE_NO_REVERSAL)
/* |v| as uint32 (2^31 for INT32_MIN) */
static uint32_t mag_i32(int32_t v)
{
    return v < 0 ? 0u - (uint32_t)v : (uint32_t)v;
}
#endif

static uint64_t abs_i32(int32_t v)
{
    return v < 0 ? (uint64_t)(-(int64_t)v) : (uint64_t)v;
}

/* The caps keep every fixed-point intermediate below 2^63 (docs/numerics.md). */
static abbe_status_t check_ranges(const uint8_t *b, uint32_t total)
{
    uint32_t features = abbe_ld_u32(b + H_FEATURES);
    for (unsigned k = 0; k < 3u; k++) {
        if (abs_i32(abbe_ld_i32(b + H_SQUARENESS + 4u * k)) > (uint64_t)SQUARENESS_CAP) {
            return ABBE_E_RANGE;
        }
    }
    for (unsigned j = 0; j < ABBE_AXES; j++) {
        const uint8_t *rec = b + HEADER_SIZE + j * AXIS_RECORD_SIZE;
        if (features & ABBE_FEATURE_BACKLASH) {
            /* A reversal needs a take-up distance to ramp over; an axis without
             * reversal may leave it 0. */
            int32_t takeup = abbe_ld_i32(rec + A_TAKEUP);
            if (takeup < 0 || (takeup == 0 && (abbe_ld_i32(rec + A_BACKLASH) != 0 || REVERSAL_ROWS(rec) != 0u))) {
                return ABBE_E_RANGE;
            }
        }
        unsigned mask = rec[A_MASK];
        unsigned n_terms = popcount6(mask);
        uint32_t n_basis = n_basis_of(rec);
        uint32_t off_q = abbe_ld_u32(rec + A_COEF_Q);
        unsigned column = 0;
        for (unsigned t = 0; t < ABBE_TERMS; t++) {
            if (!((mask >> t) & 1u)) {
                continue;
            }
            uint64_t l1 = 0;
            for (uint32_t r = 0; r < n_basis; r++) {
                l1 += abs_i32(abbe_u32_to_i32(coef_word(b, total, off_q, r * n_terms + column)));
            }
            if (l1 > (t < 3u ? LIN_L1_CAP : ANG_L1_CAP)) {
                return ABBE_E_RANGE;
            }
            column++;
        }
#if !defined(ABBE_NO_REVERSAL)
        /* the total reversal |B + R(p)| <= |B| + sum |r_k| <= 2^31 (keeps
         * s (B + R) below 2^62), counted down in 32 bits */
        uint32_t left = REVERSAL_L1_CAP - mag_i32(abbe_ld_i32(rec + A_BACKLASH));
        for (unsigned k = 0; k < REVERSAL_ROWS(rec); k++) {
            uint32_t a = mag_i32(abbe_u32_to_i32(coef_word(b, total, off_q, n_basis * n_terms + k)));
            if (a > left) {
                return ABBE_E_RANGE;
            }
            left -= a;
        }
#endif
    }
    return ABBE_OK;
}

/* round(2^64 / d) for 0 < d < 2^31, without a 128-bit type. */
ABBE_NOINLINE static uint64_t recip64(uint32_t d)
{
    uint64_t q = UINT64_MAX / d;
    uint64_t r = UINT64_MAX % d + 1u; /* 2^64 = q*d + r, 1 <= r <= d */
    if (r == d) {
        return q + 1u;
    }
    return q + (2u * r >= d ? 1u : 0u);
}

/* Number of significant bits of v > 0 (one CLZ where the compiler has it). */
static unsigned bit_length(uint32_t v)
{
#if defined(__GNUC__)
    return 32u - (unsigned)__builtin_clz(v);
#else
    unsigned n = 0;
    while (v != 0u) {
        v >>= 1;
        n++;
    }
    return n;
#endif
}

static void build_axis(abbe_axis_model_t *ax, const uint8_t *b, const uint8_t *rec)
{
    memset(ax, 0, sizeof *ax);
    ax->travel_min_nm = abbe_ld_i32(rec + A_MIN);
    ax->travel_max_nm = abbe_ld_i32(rec + A_MAX);
    ax->term_mask = rec[A_MASK];
    ax->n_terms = (uint8_t)popcount6(ax->term_mask);
    ax->trend_rows = (uint8_t)trend_rows_of(rec[A_DEGREE]);
    ax->n_basis = (uint8_t)n_basis_of(rec);
    uint8_t column = 0;
    for (unsigned t = 0; t < ABBE_TERMS; t++) {
        if (((unsigned)ax->term_mask >> t) & 1u) {
            ax->column[t] = column++;
        } else {
            ax->column[t] = 0xFFu;
        }
    }
    if (abbe_ld_u32(rec + A_COEF_COUNT) != 0u) {
        ax->coef_q = b + abbe_ld_u32(rec + A_COEF_Q);
        ax->coef_f32 = b + abbe_ld_u32(rec + A_COEF_F32);
    }
    /* Chebyshev argument (abbe_arg_cheb_q30): with n the bit length of the
     * span, shift = 32 - n keeps d << shift below 2^32, and
     * cheb_mul = round(2^(31 + n) / span) lies in (2^31, 2^32], 2^32 only for
     * a power-of-two span, stored as 2^32 - 1 (exact all the same there:
     * d << shift <= 2^31, internal.h). */
    uint32_t span = (uint32_t)ax->travel_max_nm - (uint32_t)ax->travel_min_nm; /* < 2^32, > 0 */
    span = span != 0u ? span : 1u; /* never binds (check_travel): the divisor's bound, stated for the proof */
    unsigned n = bit_length(span);
    uint64_t mul = (((uint64_t)1 << (31u + n)) + span / 2u) / span;
    ax->span_nm = span;
    ax->cheb_shift = (uint8_t)(32u - n);
    ax->cheb_mul = mul > UINT32_MAX ? UINT32_MAX : (uint32_t)mul;
    for (unsigned k = 0; k < ABBE_BLOCKS; k++) {
        ax->harmonics[k] = rec[A_HARMONICS + k];
        int32_t origin = abbe_ld_i32(rec + A_ORIGIN + 4u * k);
        int32_t period = abbe_ld_i32(rec + A_PERIOD + 4u * k);
        ax->freq[k] = period > 0 ? recip64((uint32_t)period) : 0u;
        /* phase of travel_min, so an evaluation multiplies only d = p - min */
        uint64_t from_origin = (uint64_t)((int64_t)ax->travel_min_nm - origin); /* mod 2^64 */
        ax->phase_min[k] = from_origin * ax->freq[k];
    }
    ax->backlash_reversal_q8 = abbe_ld_i32(rec + A_BACKLASH);
    const int32_t takeup_nm = abbe_ld_i32(rec + A_TAKEUP); /* a local: the divisor's test is where it is read */
    ax->backlash_takeup_nm = takeup_nm;
    if (takeup_nm > 0) {
        uint64_t takeup = (uint64_t)takeup_nm;
        ax->takeup_rate_q46 = (((uint64_t)1 << 46) + takeup / 2u) / takeup;
    }
    ax->thermal_expansion_q50 = abbe_ld_i32(rec + A_EXPANSION);
    ax->thermal_offset_q16 = abbe_ld_i32(rec + A_THERMAL_OFFSET);
    ax->thermal_tref_mdegc = abbe_ld_i32(rec + A_TREF);
#if !defined(ABBE_NO_REVERSAL)
    ax->reversal_rows = rec[A_REVERSAL_ROWS];
#endif
}

/* The constants of Eq. 3 that do not depend on the position (abbe_eval_*_core). */
static void build_assembly(abbe_model_t *m)
{
    const int64_t sxy = m->squareness_q36[0], sxz = m->squareness_q36[1], syz = m->squareness_q36[2];
    for (unsigned k = 0; k < ABBE_AXES; k++) {
        const abbe_axis_model_t *ax = &m->axis[k];
        m->ref_half_nm[k] = m->reference_nm[k] >> 1;
        m->any_block1 |= (uint8_t)(ax->harmonics[1] != 0u);
#if defined(ABBE_X86_LANES)
        m->lane_min_nm[k] = ax->travel_min_nm;
        m->lane_max_nm[k] = ax->travel_max_nm;
        m->lane_span_nm[k] = ax->span_nm;
        m->lane_cheb_shift[k] = ax->cheb_shift;
        m->lane_cheb_mul[k] = ax->cheb_mul;
#if defined(ABBE_MODEL_X86_64_LANES)
        for (unsigned b = 0; b < ABBE_BLOCKS; b++) {
            m->lane_freq[b][k] = ax->freq[b];
            m->lane_phase_min[b][k] = ax->phase_min[b];
        }
#endif
#endif
#if ABBE_WITH_F32
        /* converted in the FPU (rounded to nearest even, the rounding of
         * i32_to_f32_bits); t / 2 is exact (|t| >= 1 is far from the
         * subnormals). Not through the bits: the proof (docs/proofs.md) sees
         * a converted integer is finite, not that a bit pattern is. */
        m->tool_half_nm[k] = (float)m->tool_offset_nm[k] * 0.5f;
        m->squareness_f[k] = (float)m->squareness_q36[k];
#endif
    }
#if defined(ABBE_X86_LANES)
    /* negated before the conversion (sign-symmetric, so exact); |S| <= 2^28 */
    m->square_dx_dy[0] = m->squareness_f[0];
    m->square_dx_dy[1] = (float)-m->squareness_q36[2];
    m->square_dx_f[0] = (float)-m->squareness_q36[1];
#endif
    /* dX has y S_xy - z S_xz, dY has -z S_yz, with y = p_y - ref_y, z = p_z - ref_z:
     * the ref parts are constants (|ref * S| <= 2^59). */
    m->square_const_q36[0] = -(int64_t)m->reference_nm[1] * sxy + (int64_t)m->reference_nm[2] * sxz;
    m->square_const_q36[1] = (int64_t)m->reference_nm[2] * syz;
}

/* The checks of docs/table-format.md in their order, over the header and the
 * three linear axes, into st (total: the table's size). rotary: 0 for
 * abbe_model_load (a 1.2 table is refused by its minor), ABBE_FEATURE_ROTARY
 * for the five-axis loader (five_load.c), which then checks the rotary
 * section itself; with ROTARY set the linear axes' arrays start after that
 * section. A macro, not an inline function: GCC then compiles the 3-axis
 * loader exactly as before format 1.2 (an inline wrapper cost 88 B there). */
#define CHECK_TABLE(st, b, size, total, rotary)                                                                     \
    do {                                                                                                           \
        (st) = check_header((b), (size), &(total), (rotary));                                                      \
        if ((st) == ABBE_OK) { (st) = check_flags((b), (rotary)); }                                                \
        if ((st) == ABBE_OK) { (st) = check_counts(b); }                                                           \
        if ((st) == ABBE_OK) {                                                                                     \
            (st) = check_offsets((b), (total),                                                                     \
                                 (abbe_ld_u32((b) + H_FEATURES) & (rotary)) != 0u ? ABBE_ROTARY_DATA_START        \
                                                                                  : DATA_START);                  \
        }                                                                                                          \
        if ((st) == ABBE_OK) { (st) = check_finite((b), (total)); }                                                \
        if ((st) == ABBE_OK) { (st) = check_twins((b), (total)); }                                                 \
        if ((st) == ABBE_OK) { (st) = check_periods(b); }                                                          \
        if ((st) == ABBE_OK) { (st) = check_travel(b); }                                                           \
        if ((st) == ABBE_OK) { (st) = check_ranges((b), (total)); }                                                \
    } while (0)

/* *model as a view of the validated table b. */
static ABBE_ALWAYS_INLINE void build_model(abbe_model_t *model, const uint8_t *b, uint32_t total)
{
    memset(model, 0, sizeof *model);
    model->blob = b;
    model->size = total;
    model->crc = abbe_ld_u32(b + total - 4u);
    model->features = abbe_ld_u32(b + H_FEATURES);
    model->version_major = abbe_ld_u16(b + H_MAJOR);
    model->version_minor = abbe_ld_u16(b + H_MINOR);
    for (unsigned k = 0; k < 3u; k++) {
        model->reference_nm[k] = abbe_ld_i32(b + H_REFERENCE + 4u * k);
        model->tool_offset_nm[k] = abbe_ld_i32(b + H_TOOL + 4u * k);
        model->squareness_q36[k] = abbe_ld_i32(b + H_SQUARENESS + 4u * k);
    }
    for (unsigned j = 0; j < ABBE_AXES; j++) {
        build_axis(&model->axis[j], b, b + HEADER_SIZE + j * AXIS_RECORD_SIZE);
    }
    build_assembly(model);
#if defined(ABBE_X86_V3)
    model->simd = abbe_simd_level();
#endif
}

#if defined(ABBE_MODEL_LOAD_THERMAL)
/* thermal_load.c: abbe_thermal_load follows the include */
#elif !defined(ABBE_MODEL_LOAD_FIVE) /* the 3-axis loader's translation unit */
abbe_status_t abbe_model_load(abbe_model_t *model, const void *blob, size_t size)
{
    if (model == NULL || blob == NULL) {
        return ABBE_E_ARG;
    }
    /* Coefficients are read in place with word loads (one vldr per float on a
     * Cortex-M4F), so the table must start on a 4-byte boundary. */
    if (((uintptr_t)blob & 3u) != 0u) {
        return ABBE_E_ALIGN;
    }
    const uint8_t *b = (const uint8_t *)blob;
    uint32_t total = 0;
    abbe_status_t st;
    CHECK_TABLE(st, b, size, total, 0u);
    if (st != ABBE_OK) {
        return st;
    }
    /* Every check above only read the blob: *model is written from here on,
     * after the last possible failure, so a refused table leaves it untouched
     * (and no second abbe_model_t is needed on the stack). */
    build_model(model, b, total);
    return ABBE_OK;
}

uint32_t abbe_model_crc(const abbe_model_t *model)
{
    return model != NULL ? model->crc : 0u;
}

uint32_t abbe_model_features(const abbe_model_t *model)
{
    return model != NULL ? model->features : 0u;
}

size_t abbe_model_sizeof(void)
{
    return sizeof(abbe_model_t);
}

uint32_t abbe_model_size(const abbe_model_t *model)
{
    return model != NULL ? model->size : 0u;
}

abbe_status_t abbe_model_axis_info(const abbe_model_t *model, unsigned axis, abbe_axis_info_t *info)
{
    if (model == NULL || info == NULL || axis >= ABBE_AXES) {
        return ABBE_E_ARG;
    }
    const abbe_axis_model_t *ax = &model->axis[axis];
    info->travel_min_nm = ax->travel_min_nm;
    info->travel_max_nm = ax->travel_max_nm;
    info->backlash_takeup_nm = (model->features & ABBE_FEATURE_BACKLASH) ? ax->backlash_takeup_nm : 0;
    info->thermal_tref_mdegc = (model->features & ABBE_FEATURE_THERMAL) ? ax->thermal_tref_mdegc : 0;
    return ABBE_OK;
}

#else /* five_load.c: the five-axis loader, with its own copies of the checks */

/* ---- the rotary section of a five-axis table (format 1.2; abbe/five_axis.h) ----
 * Compiled only into five_load.c, which includes this file: the five-axis
 * loader gets its own copies of the checks above (inlined with rotary =
 * ABBE_FEATURE_ROTARY), and the 3-axis loader's translation unit is what it
 * was before format 1.2, byte for byte in flash (bench/results.md). */

#define RH_KIND 0u
#define RH_ROT_POINT 4u
#define RH_OFFSET 16u
#define RH_SQUARENESS 28u
#define RH_RESERVED 40u /* 24 bytes */
#define RA_LOC_LIN 0u
#define RA_LOC_ANG 8u
#define RA_MASK 20u
#define RA_HARMONICS 21u
#define RA_RESERVED0 22u /* 2 bytes */
#define RA_COEF_Q 24u
#define RA_COEF_F32 28u
#define RA_COEF_COUNT 32u
#define RA_RESERVED 36u /* 28 bytes */
#define GEOMETRY_CAP (((int32_t)1 << 30) - 1) /* |rot_point|, |offset| < 1073.7 mm: their sum fits an int32 */
#define RH_SQUARE_REF 40u /* 1.4, kinds 3-5: i32[3], then 12 reserved bytes */
#define RA_SIGN 22u       /* 1.4, kinds 3-5: 0 (+1) or 1 (-1), then 1 reserved byte */
#define KIND_CHAIN(kind) ((kind) >= ABBE_KIN_XYZBC_HH)

static const uint8_t *rotary_record(const uint8_t *b, unsigned r)
{
    return b + ABBE_ROTARY_HEADER_OFFSET + ABBE_ROTARY_HEADER_SIZE + r * ABBE_ROTARY_RECORD_SIZE;
}

static int any_nonzero_u8(const uint8_t *p, unsigned count)
{
    for (unsigned i = 0; i < count; i++) {
        if (p[i] != 0u) {
            return 1;
        }
    }
    return 0;
}

/* Whether any of the count int32 at p has |v| > cap. */
static int any_above(const uint8_t *p, unsigned count, uint32_t cap)
{
    for (unsigned i = 0; i < count; i++) {
        if (mag_i32(abbe_ld_i32(p + 4u * i)) > cap) {
            return 1;
        }
    }
    return 0;
}

/* The categories of the rotary records' checks, in the loader's order. */
enum { RC_FLAGS, RC_COUNT, RC_OFFSET, RC_NONFINITE, RC_MISMATCH, RC_RANGE, RC_CATEGORIES };

/* Whether rotary record rec fails the checks of category cat. One function
 * for all categories, called per category and axis (check_rotary): the
 * loader is cold, and one copy of each check is 300 B less flash than the
 * loops unrolled per category (bench/results.md, section 11). */
static ABBE_NOINLINE int rotary_record_bad(const uint8_t *b, const uint8_t *rec, uint32_t total, unsigned cat)
{
    unsigned mask = rec[RA_MASK], rows = 2u * rec[RA_HARMONICS], n_comp = popcount6(mask);
    uint32_t count = abbe_ld_u32(rec + RA_COEF_COUNT);
    uint32_t off_q = abbe_ld_u32(rec + RA_COEF_Q), off_f = abbe_ld_u32(rec + RA_COEF_F32);
    switch (cat) {
    case RC_FLAGS:
#if defined(ABBE_NO_FIVE_KINDS)
        return any_nonzero_u8(rec + RA_RESERVED0, 2u) || any_nonzero_u8(rec + RA_RESERVED, 28u);
#else /* kinds 3-5: the direction byte 0 or 1 */
        return rec[RA_RESERVED0] > (KIND_CHAIN(b[ABBE_ROTARY_HEADER_OFFSET + RH_KIND]) ? 1u : 0u) ||
               rec[RA_RESERVED0 + 1u] != 0u || any_nonzero_u8(rec + RA_RESERVED, 28u);
#endif
    case RC_COUNT:
        return (mask & 0xC0u) != 0u || rec[RA_HARMONICS] > ABBE_ROTARY_MAX_HARMONICS || count != rows * n_comp;
    case RC_OFFSET:
        return count == 0u ? (off_q | off_f) != 0u
                           : (!array_ok(off_q, count, total, ABBE_ROTARY_DATA_START) ||
                              !array_ok(off_f, count, total, ABBE_ROTARY_DATA_START));
    case RC_NONFINITE:
    case RC_MISMATCH:
        for (uint32_t i = 0; i < count; i++) {
            uint32_t bits = coef_word(b, total, off_f, i);
            if (cat == RC_NONFINITE ? abbe_f32_bits_nonfinite(bits)
                                    : bits != i32_to_f32_bits(abbe_u32_to_i32(coef_word(b, total, off_q, i)))) {
                return 1;
            }
        }
        return 0;
    default: { /* RC_RANGE */
        if (any_above(rec + RA_LOC_ANG, 3u, (uint32_t)SQUARENESS_CAP)) {
            return 1;
        }
        unsigned column = 0;
        for (unsigned c = 0; c < ABBE_MOTIONS; c++) {
            if (!((mask >> c) & 1u)) {
                continue;
            }
            uint64_t l1 = 0;
            for (unsigned row = 0; row < rows; row++) {
                l1 += mag_i32(abbe_u32_to_i32(coef_word(b, total, off_q, row * n_comp + column)));
            }
            if (l1 > (c < 3u ? LIN_L1_CAP : ANG_L1_CAP)) {
                return 1;
            }
            column++;
        }
        return 0;
    }
    }
}

/* The rotary checks in the loader's category order (after every check of the
 * header and the linear axes): FLAGS, COUNT, OFFSET, NONFINITE, MISMATCH, RANGE,
 * each over the rotary header (FLAGS, RANGE) and both rotary records. */
static abbe_status_t check_rotary(const uint8_t *b, uint32_t total)
{
    static const abbe_status_t code[RC_CATEGORIES] = {ABBE_E_FLAGS,     ABBE_E_COUNT,    ABBE_E_OFFSET,
                                                      ABBE_E_NONFINITE, ABBE_E_MISMATCH, ABBE_E_RANGE};
    const uint8_t *h = b + ABBE_ROTARY_HEADER_OFFSET;
    unsigned kind = h[RH_KIND];
    /* the offset has no component along the tilt axis: AC (0, y, z), BC (x, 0, z); kinds 3-5
     * (format 1.4) carry the squareness' reference point in the first 12 reserved bytes */
#if defined(ABBE_NO_FIVE_KINDS)
    const unsigned chain = 0u;
#else
    const unsigned chain =
        (kind >= ABBE_KIN_XYZBC_HH && kind <= ABBE_KIN_XYZAB_TDR && abbe_ld_u16(b + H_MINOR) >= 4u) ? 1u : 0u;
#endif
    /* a trunnion kind (tested in this form so that the analysis knows kind is 1 or 2 where
     * it indexes the offset with it: docs/proofs.md) */
    if (chain == 0u && ((kind != ABBE_KIN_XYZAC_TRT && kind != ABBE_KIN_XYZBC_TRT) ||
                        abbe_ld_u32(h + RH_OFFSET + 4u * (kind - 1u)) != 0u)) {
        return ABBE_E_FLAGS;
    }
    if (any_nonzero_u8(h + 1u, 3u) || any_nonzero_u8(h + RH_RESERVED + 12u * chain, 24u - 12u * chain)) {
        return ABBE_E_FLAGS;
    }
    for (unsigned cat = 0; cat < RC_CATEGORIES; cat++) {
        /* the header's range: rot_point and offset (contiguous) then its squareness */
        if (cat == RC_RANGE && (any_above(h + RH_ROT_POINT, 6u, (uint32_t)GEOMETRY_CAP) ||
                                any_above(h + RH_SQUARENESS, 3u, (uint32_t)SQUARENESS_CAP) ||
                                (chain && any_above(h + RH_SQUARE_REF, 3u, (uint32_t)GEOMETRY_CAP)))) {
            return ABBE_E_RANGE;
        }
        for (unsigned r = 0; r < ABBE_ROTARY_AXES; r++) {
            if (rotary_record_bad(b, rotary_record(b, r), total, cat)) {
                return code[cat];
            }
        }
    }
    return ABBE_OK;
}

/* The two machine axes other than dir, in increasing order: where an axis'
 * two location positions and two tilts go (ISO 230-1: EX0C, EY0C for C). */
static void others_of(unsigned dir, unsigned *i1, unsigned *i2)
{
    *i1 = dir == 0u ? 1u : 0u;
    *i2 = dir == 2u ? 1u : 2u;
}

static void build_rotary(abbe_rotary_model_t *ax, const uint8_t *b, const uint8_t *rec, unsigned dir)
{
    memset(ax, 0, sizeof *ax);
    unsigned i1, i2;
    others_of(dir, &i1, &i2);
    ax->dir = (uint8_t)dir;
    ax->delta_q8[i1] = abbe_ld_i32(rec + RA_LOC_LIN);
    ax->delta_q8[i2] = abbe_ld_i32(rec + RA_LOC_LIN + 4u);
    ax->phi_q36[i1] = abbe_ld_i32(rec + RA_LOC_ANG);
    ax->phi_q36[i2] = abbe_ld_i32(rec + RA_LOC_ANG + 4u);
    ax->zero_q36 = abbe_ld_i32(rec + RA_LOC_ANG + 8u);
    ax->comp_mask = rec[RA_MASK];
    ax->n_comp = (uint8_t)popcount6(ax->comp_mask);
    /* no component, no coefficient arrays (NULL): the kernels' row pointer must
     * not be stepped through harmonics that have nothing to read */
    ax->harmonics = ax->n_comp != 0u ? rec[RA_HARMONICS] : (uint8_t)0u;
    uint8_t column = 0;
    for (unsigned c = 0; c < ABBE_MOTIONS; c++) {
        if (((unsigned)ax->comp_mask >> c) & 1u) {
            ax->column[c] = column++;
        } else {
            ax->column[c] = 0xFFu;
        }
    }
    if (abbe_ld_u32(rec + RA_COEF_COUNT) != 0u) {
        ax->coef_q = b + abbe_ld_u32(rec + RA_COEF_Q);
        ax->coef_f32 = b + abbe_ld_u32(rec + RA_COEF_F32);
    }
}

abbe_status_t abbe_five_model_load(abbe_five_model_t *model, const void *blob, size_t size)
{
    if (model == NULL || blob == NULL) {
        return ABBE_E_ARG;
    }
    if (((uintptr_t)blob & 3u) != 0u) {
        return ABBE_E_ALIGN;
    }
    const uint8_t *b = (const uint8_t *)blob;
    uint32_t total = 0;
    abbe_status_t st;
    CHECK_TABLE(st, b, size, total, ABBE_FEATURE_ROTARY);
    /* total >= ABBE_ROTARY_DATA_START + 4 follows from check_header for a
     * ROTARY table; stated here, where the rotary records are read, for the
     * proof (docs/proofs.md) */
    const int rotary = st == ABBE_OK && (abbe_ld_u32(b + H_FEATURES) & ABBE_FEATURE_ROTARY) != 0u &&
                       total >= ABBE_ROTARY_DATA_START + 4u;
    if (rotary) {
        st = check_rotary(b, total);
    }
    if (st != ABBE_OK) {
        return st; /* *model untouched */
    }
    memset(model, 0, sizeof *model);
    build_model(&model->linear, b, total);
    model->linear.five_view = 1u; /* the compensator's five-axis step may read the whole model */
    if (!rotary) {
        return ABBE_OK; /* a 3-axis table: no rotary errors, kind NONE */
    }
    const uint8_t *h = b + ABBE_ROTARY_HEADER_OFFSET;
    const uint32_t kind = h[RH_KIND];
    model->kind = kind;
    for (unsigned k = 0; k < 3u; k++) {
        model->rot_point_nm[k] = abbe_ld_i32(h + RH_ROT_POINT + 4u * k);
        model->offset_nm[k] = abbe_ld_i32(h + RH_OFFSET + 4u * k);
        /* |.| <= 2^31 - 2 (GEOMETRY_CAP): fits, so the sum mod 2^32 is the sum */
        model->tilt_pivot_nm[k] = abbe_u32_to_i32((uint32_t)model->rot_point_nm[k] + (uint32_t)model->offset_nm[k]);
        model->squareness_q36[k] = abbe_ld_i32(h + RH_SQUARENESS + 4u * k);
    }
#if !defined(ABBE_NO_FIVE_KINDS)
    if (kind >= ABBE_KIN_XYZBC_HH && kind <= ABBE_KIN_XYZAB_TDR) { /* validated: check_rotary */
        /* record 0's and record 1's machine axes and angle slots (A, B, C in alphabetical order):
         * 3 C, B; 4 B, C; 5 B, A */
        static const uint8_t dirs[3][2] = {{2u, 1u}, {1u, 2u}, {1u, 0u}};
        const unsigned i = kind - ABBE_KIN_XYZBC_HH;
        for (unsigned r = 0; r < ABBE_ROTARY_AXES; r++) {
            build_rotary(&model->rotary[r], b, rotary_record(b, r), dirs[i][r]);
            model->sign[r] = rotary_record(b, r)[RA_SIGN] != 0u ? (int8_t)-1 : (int8_t)1;
            model->slot[r] = (uint8_t)(i == 1u ? r : 1u - r);
        }
        for (unsigned k = 0; k < 3u; k++) {
            model->square_ref_nm[k] = abbe_ld_i32(h + RH_SQUARE_REF + 4u * k);
        }
        return ABBE_OK;
    }
#endif
    build_rotary(&model->rotary[0], b, rotary_record(b, 0), model->kind == ABBE_KIN_XYZAC_TRT ? 0u : 1u);
    build_rotary(&model->rotary[1], b, rotary_record(b, 1), 2u);
    return ABBE_OK;
}

uint32_t abbe_five_model_kind(const abbe_five_model_t *model)
{
    return model != NULL ? model->kind : ABBE_KIN_NONE;
}

size_t abbe_five_model_sizeof(void)
{
    return sizeof(abbe_five_model_t);
}
#endif /* ABBE_MODEL_LOAD_FIVE */

/* abbe: the checks of docs/table-format.md over a table's header and its
 * three linear axes, each a function over all axes, run in the spec's order
 * by CHECK_TABLE (at the end), so a table with several defects reports the
 * same status here and in the Python reader. They only read the table: the
 * model is written after the last of them passed (model_load_view.h).
 * Part of model_load.c (see model_load_layout.h for why a header of static
 * functions); the five-axis and thermal loaders compile the same checks with
 * ABBE_MODEL_LOAD_FIVE / ABBE_MODEL_LOAD_THERMAL. Not installed. */
#ifndef ABBE_MODEL_LOAD_CHECKS_H
#define ABBE_MODEL_LOAD_CHECKS_H

#include "model_load_layout.h"

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
    /*@ WP_LOOP_COUNTS */
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
    return v < 0 ? (uint32_t)(-(int64_t)v) : (uint32_t)v; /* -v <= 2^31: no wrap */
}
#endif

static uint64_t abs_i32(int32_t v)
{
    return v < 0 ? (uint64_t)(-(int64_t)v) : (uint64_t)v;
}

/* sum |c| over the n_basis words of one term's column of the int32 matrix
 * at off_q (row r's word r * n_terms + column), in uint64: at most
 * 2^32 rows of 2^31 each, below 2^63 (WP: column_l1, model_load_acsl.h) */
static uint64_t column_l1_of(const uint8_t *b, uint32_t total, uint32_t off_q, uint32_t n_basis, unsigned n_terms,
                             unsigned column)
{
    uint64_t l1 = 0;
    /*@ WP_LOOP_L1_ROWS */
    for (uint32_t r = 0; r < n_basis; r++) {
        /*@ WP_L1_ROW */
        l1 += abs_i32(abbe_u32_to_i32(coef_word(b, total, off_q, r * n_terms + column)));
    }
    return l1;
}

/* The header's squareness words within SQUARENESS_CAP (WP:
 * squareness_caps, model_load_acsl.h). The words read as abbe_ld_i32 does,
 * spelt as its two steps so that only this function's proof sees their value. */
static abbe_status_t check_squareness(const uint8_t *b)
{
    /*@ WP_LOOP_SQUARENESS */
    for (unsigned k = 0; k < 3u; k++) {
        if (abs_i32(abbe_u32_to_i32(abbe_ld_u32(b + H_SQUARENESS + 4u * k))) > (uint64_t)SQUARENESS_CAP) {
            return ABBE_E_RANGE;
        }
    }
    return ABBE_OK;
}

#if !defined(ABBE_NO_REVERSAL)
/* Per axis the total reversal |B + R(p)| <= |B| + sum |r_k| <= 2^31 (keeps
 * s (B + R) below 2^62), counted down in 32 bits (WP: reversal_caps,
 * model_load_acsl.h). Its own loop over the axes after the L1 caps' one: each
 * check returns ABBE_E_RANGE, so a table refused by both is refused with the
 * same status whichever comes first; apart, each proof's goals stay small. */
static abbe_status_t check_reversal(const uint8_t *b, uint32_t total)
{
    /*@ WP_LOOP_REV_AXES */
    for (unsigned j = 0; j < ABBE_AXES; j++) {
        const uint8_t *rec = b + HEADER_SIZE + j * AXIS_RECORD_SIZE;
        const uint32_t base = n_basis_of(rec) * popcount6(rec[A_MASK]); /* the rows after the matrix */
        const uint32_t off_q = abbe_ld_u32(rec + A_COEF_Q);
        uint32_t left = REVERSAL_L1_CAP - mag_i32(abbe_u32_to_i32(abbe_ld_u32(rec + A_BACKLASH)));
        /*@ WP_LOOP_REVERSAL_LEFT */
        for (unsigned k = 0; k < REVERSAL_ROWS(rec); k++) {
            /*@ WP_REV_NEXT */
            uint32_t a = mag_i32(abbe_u32_to_i32(coef_word(b, total, off_q, base + k)));
            if (a > left) {
                return ABBE_E_RANGE;
            }
            /*@ WP_REV_WRAP */
            left -= a;
        }
        /*@ WP_REV_RECORD */
        /*@ WP_REV_AXIS */
    }
    return ABBE_OK;
}
#endif

/* The caps keep every fixed-point intermediate below 2^63 (docs/numerics.md). */
static abbe_status_t check_ranges(const uint8_t *b, uint32_t total)
{
    uint32_t features = abbe_ld_u32(b + H_FEATURES);
    /*@ WP_LOOP_L1_AXES */
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
        /*@ WP_LOOP_L1_TERMS */
        for (unsigned t = 0; t < ABBE_TERMS; t++) {
            if (!((mask >> t) & 1u)) {
                /*@ WP_L1_ABSENT */
                continue;
            }
            if (column_l1_of(b, total, off_q, n_basis, n_terms, column) > (t < 3u ? LIN_L1_CAP : ANG_L1_CAP)) {
                return ABBE_E_RANGE;
            }
            /*@ WP_L1_PRESENT */
            column++;
        }
        /*@ WP_L1_AXIS */
    }
    /* after the L1 caps' loop (any failure here is ABBE_E_RANGE too): that
     * loop's proof then does not carry these caps' facts */
    if (check_squareness(b) != ABBE_OK) {
        return ABBE_E_RANGE;
    }
#if !defined(ABBE_NO_REVERSAL)
    return check_reversal(b, total);
#else
    return ABBE_OK;
#endif
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

#endif /* ABBE_MODEL_LOAD_CHECKS_H */

/* abbe: the rotary section of a five-axis table (format 1.2, kinds 3-5 in
 * 1.4; abbe/five_axis.h, docs/table-format.md): its layout, its checks and
 * its rotary axes' model view.
 * Compiled only into five_load.c, which includes model_load.c: the five-axis
 * loader gets its own copies of the checks of model_load_checks.h (inlined
 * with rotary = ABBE_FEATURE_ROTARY), and the 3-axis loader's translation
 * unit is what it was before format 1.2, byte for byte in flash
 * (bench/results.md). Not installed. */
#ifndef ABBE_MODEL_LOAD_ROTARY_H
#define ABBE_MODEL_LOAD_ROTARY_H

#include "model_load_checks.h"
#include "model_load_rotary_acsl.h"

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
/* Kind 3 (head-head): |offset|_1 + |rot_point + offset|_1 (nm, sums of the components'
 * magnitudes) at most 2^32 - 2^10 nm (4.294 m). The fixed-point evaluation keeps the head's
 * lever R0 (P0 - P1 + R1 P1) (P0 = rot_point, P1 = rot_point + offset) as an int32 of 2 nm;
 * each of its components is at most |P0 - P1|_2 + |P1|_2 <= this sum (half of it in 2 nm)
 * plus a few LSB of the halvings and rotations: within 2^31 - 1 with 2^9 LSB to spare
 * (five_eval_q.c chain_q, docs/table-format.md). Kinds 4 and 5 fit by the caps alone. */
#define HH_LEVER_L1_CAP 0xFFFFFC00u /* 2^32 - 2^10 */

static const uint8_t *rotary_record(const uint8_t *b, unsigned r)
{
    return b + ABBE_ROTARY_HEADER_OFFSET + ABBE_ROTARY_HEADER_SIZE + r * ABBE_ROTARY_RECORD_SIZE;
}

static int any_nonzero_u8(const uint8_t *p, unsigned count)
{
    /*@ WP_LOOP_ROT_BYTES */
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
    /*@ WP_LOOP_ROT_WORDS */
    for (unsigned i = 0; i < count; i++) {
        if (mag_i32(abbe_ld_i32(p + 4u * i)) > cap) {
            return 1;
        }
    }
    return 0;
}

/* Whether a kind 3 table's head lever (HH_LEVER_L1_CAP) is beyond the _q evaluation's
 * int32 range; h is the rotary header (rot_point, offset within GEOMETRY_CAP). */
static int hh_lever_too_long(const uint8_t *h)
{
    uint32_t left = HH_LEVER_L1_CAP; /* spent per component (each at most 3 x 2^30): exact in uint32 */
    /*@ WP_LOOP_ROT_LEVER */
    for (unsigned k = 0; k < 3u; k++) {
        const uint32_t off = abbe_ld_u32(h + RH_OFFSET + 4u * k);
        /* |rot_point|, |offset| <= GEOMETRY_CAP: the sum fits an int32 (as tilt_pivot_nm) */
        const uint32_t a = mag_i32(abbe_u32_to_i32(off)) +
                           mag_i32(abbe_u32_to_i32(off + abbe_ld_u32(h + RH_ROT_POINT + 4u * k)));
        if (a > left) {
            return 1;
        }
        left -= a;
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
        /*@ WP_LOOP_ROT_COEFS */
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
        /*@ WP_LOOP_ROT_COMPONENTS */
        for (unsigned c = 0; c < ABBE_MOTIONS; c++) {
            if (!((mask >> c) & 1u)) {
                continue;
            }
            uint64_t l1 = 0;
            /*@ WP_LOOP_ROT_ROWS */
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
#if ABBE_FIVE_KIND_MASK != 0x3Eu && !(defined(ABBE_NO_FIVE_KINDS) && ABBE_FIVE_KIND_MASK == 0x06u)
    /* a kind this library was built without (ABBE_FIVE_KINDS): kind is 1..5 here */
    if (ABBE_FIVE_KIND_BUILT(kind) == 0u) {
        return ABBE_E_KIND;
    }
#endif
    if (any_nonzero_u8(h + 1u, 3u) || any_nonzero_u8(h + RH_RESERVED + 12u * chain, 24u - 12u * chain)) {
        return ABBE_E_FLAGS;
    }
    /*@ WP_LOOP_ROT_CATEGORIES */
    for (unsigned cat = 0; cat < RC_CATEGORIES; cat++) {
        /* the header's range: rot_point and offset (contiguous) then its squareness */
        if (cat == RC_RANGE && (any_above(h + RH_ROT_POINT, 6u, (uint32_t)GEOMETRY_CAP) ||
                                any_above(h + RH_SQUARENESS, 3u, (uint32_t)SQUARENESS_CAP) ||
                                (chain && (any_above(h + RH_SQUARE_REF, 3u, (uint32_t)GEOMETRY_CAP) ||
                                           (kind == ABBE_KIN_XYZBC_HH && hh_lever_too_long(h)))))) {
            return ABBE_E_RANGE;
        }
        /*@ WP_LOOP_ROT_RECORDS */
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

/* The rotary section's fields as the model keeps them, within the caps
 * check_rotary refused beyond (capped_i32, model_load_view.h): a length
 * (GEOMETRY_CAP) or an angle (SQUARENESS_CAP) at p. */
static int32_t geometry_at(const uint8_t *p)
{
    return capped_i32(abbe_ld_i32(p), GEOMETRY_CAP);
}

static int32_t angle_at(const uint8_t *p)
{
    return capped_i32(abbe_ld_i32(p), SQUARENESS_CAP);
}

static void build_rotary(abbe_rotary_model_t *ax, const uint8_t *b, const uint8_t *rec, unsigned dir)
{
    /* every field written, no memset: WP's Typed memory model does not see through
     * memset's char pointer (docs/proofs.md, "Five-axis: the rotary records"); the
     * caller has zeroed the whole model, padding included */
    unsigned i1, i2;
    others_of(dir, &i1, &i2);
    ax->dir = (uint8_t)dir;
    ax->delta_q8[dir] = 0;
    ax->phi_q36[dir] = 0;
    ax->delta_q8[i1] = abbe_ld_i32(rec + RA_LOC_LIN);
    ax->delta_q8[i2] = abbe_ld_i32(rec + RA_LOC_LIN + 4u);
    ax->phi_q36[i1] = angle_at(rec + RA_LOC_ANG);
    ax->phi_q36[i2] = angle_at(rec + RA_LOC_ANG + 4u);
    ax->zero_q36 = angle_at(rec + RA_LOC_ANG + 8u);
    ax->comp_mask = rec[RA_MASK];
    ax->n_comp = (uint8_t)popcount6(ax->comp_mask);
    /* no component, no coefficient arrays (NULL): the kernels' row pointer must
     * not be stepped through harmonics that have nothing to read */
    ax->harmonics = ax->n_comp != 0u ? rec[RA_HARMONICS] : (uint8_t)0u;
    uint8_t column = 0;
    /*@ WP_LOOP_ROT_COLUMNS */
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
    } else {
        ax->coef_q = NULL;
        ax->coef_f32 = NULL;
    }
}

#endif /* ABBE_MODEL_LOAD_ROTARY_H */

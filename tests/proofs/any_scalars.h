/* The table's scalar fields made unknown bytes (PROOF_ANY_SCALARS, the
 * eval_q.c and eval_f32.c harnesses): in the header the reference point,
 * the tool offset and the squareness; in each axis record the travel, the
 * Fourier blocks' periods and origins, the backlash reversal and take-up,
 * the thermal expansion, offset and reference temperature. What stays the
 * golden table's: the layout (version, features, counts, offsets, term
 * masks, degrees, harmonics, reversal rows), the coefficient arrays and the
 * CRC word. The real loader then runs on these bytes, so the evaluation is
 * analysed for every table it accepts with that layout and those
 * coefficients: any accepted value of every scalar field (docs/proofs.md). */
#ifndef PROOF_ANY_SCALARS_H
#define PROOF_ANY_SCALARS_H

#include "__fc_builtin.h"

/* field offsets of docs/table-format.md (lib/src/model_load_layout.h) */
#define ANY_HEADER_SIZE 64u
#define ANY_AXIS_RECORD_SIZE 64u
#define ANY_H_REFERENCE 24u    /* reference, tool offset, squareness: 3 x 3 int32 */
#define ANY_H_SCALARS_END 60u
#define ANY_A_MIN 0u           /* travel min, max */
#define ANY_A_MASK 8u          /* mask, degree, harmonics[2]: the layout, kept */
#define ANY_A_PERIOD 12u       /* periods, origins, backlash, take-up, expansion, offset, tref */
#define ANY_A_COEF_Q 48u

static void any_scalars(unsigned char *b)
{
    Frama_C_make_unknown((char *)b + ANY_H_REFERENCE, ANY_H_SCALARS_END - ANY_H_REFERENCE);
    for (unsigned j = 0; j < 3u; j++) {
        unsigned char *rec = b + ANY_HEADER_SIZE + j * ANY_AXIS_RECORD_SIZE;
        Frama_C_make_unknown((char *)rec + ANY_A_MIN, ANY_A_MASK - ANY_A_MIN);
        Frama_C_make_unknown((char *)rec + ANY_A_PERIOD, ANY_A_COEF_Q - ANY_A_PERIOD);
    }
}

#if defined(PROOF_FIVE)
/* a five-axis table (format 1.2 / 1.4): also the rotary section's scalars,
 * the rotation point, the C axis' offset and the five-axis squareness (and in
 * 1.4 their reference), and each rotary axis' location errors (linear,
 * angular); its kind, masks, harmonics, signs and arrays stay the golden
 * table's (abbe/five_axis.h, lib/src/model_load_rotary.h) */
#define ANY_RH 256u          /* rotary header */
#define ANY_RH_ROT_POINT 4u  /* rotation point, offset, squareness, square_ref: to byte 52 */
#define ANY_RH_END 52u
#define ANY_RA 320u          /* the two rotary records, 64 B each */
#define ANY_RA_LOC_END 20u   /* location errors: 2 + 3 int32 */

static void any_rotary_scalars(unsigned char *b)
{
    Frama_C_make_unknown((char *)b + ANY_RH + ANY_RH_ROT_POINT, ANY_RH_END - ANY_RH_ROT_POINT);
    for (unsigned r = 0; r < 2u; r++) {
        Frama_C_make_unknown((char *)b + ANY_RA + 64u * r, ANY_RA_LOC_END);
    }
}
#endif

#if defined(PROOF_ANY_COEFFICIENTS)
/* Every coefficient word unknown within a box inside the loader's caps
 * (PROOF_ANY_COEFFICIENTS): an axis with n basis rows gets any linear
 * coefficient in [-2^31 / n, 2^31 / n] and any angular one in [-2^27 / n,
 * 2^27 / n] (their sums of magnitudes then at most half of LIN_L1_CAP and
 * ANG_L1_CAP, so the loader's range check accepts every such array), each
 * reversal row any value in [-2^30 / r, 2^30 / r] (r rows); the float twins
 * the same values converted (the loader's twin check). The words are written
 * as int32 (the evaluation reads them as one word). */
#include <string.h>

#define ANY_A_DEGREE 9u
#define ANY_A_HARMONICS 10u
#define ANY_A_COEF_F32 52u
#define ANY_A_REVERSAL_ROWS 60u

static uint32_t any_ld_u32(const unsigned char *p)
{
    return (uint32_t)p[0] | ((uint32_t)p[1] << 8) | ((uint32_t)p[2] << 16) | ((uint32_t)p[3] << 24);
}

static void any_word(unsigned char *b, uint32_t off_q, uint32_t off_f, uint32_t i, int32_t cap)
{
    const int32_t v = Frama_C_int_interval(-cap, cap);
    const float f = (float)v;
    memcpy(b + off_q + 4u * i, &v, sizeof v);
    memcpy(b + off_f + 4u * i, &f, sizeof f);
}

static void any_coefficients(unsigned char *b)
{
    for (unsigned j = 0; j < 3u; j++) {
        const unsigned char *rec = b + ANY_HEADER_SIZE + j * ANY_AXIS_RECORD_SIZE;
        const unsigned mask = rec[ANY_A_MASK];
        const unsigned rows = (rec[ANY_A_DEGREE] == 255u ? 0u : rec[ANY_A_DEGREE] + 1u) +
                              2u * rec[ANY_A_HARMONICS] + 2u * rec[ANY_A_HARMONICS + 1u];
        const unsigned rev = rec[ANY_A_REVERSAL_ROWS];
        const uint32_t off_q = any_ld_u32(rec + ANY_A_COEF_Q), off_f = any_ld_u32(rec + ANY_A_COEF_F32);
        unsigned n_terms = 0;
        for (unsigned t = 0; t < 6u; t++) {
            n_terms += (mask >> t) & 1u;
        }
        if (rows == 0u && rev == 0u) {
            continue;
        }
        for (unsigned r = 0; r < rows; r++) {
            unsigned col = 0;
            for (unsigned t = 0; t < 6u; t++) {
                if ((mask >> t) & 1u) {
                    any_word(b, off_q, off_f, r * n_terms + col,
                             t < 3u ? (int32_t)(0x80000000u / rows) : (int32_t)(0x8000000u / rows));
                    col++;
                }
            }
        }
        for (unsigned k = 0; k < rev; k++) {
            any_word(b, off_q, off_f, rows * n_terms + k, (int32_t)(0x40000000u / rev));
        }
    }
}
#endif

#endif /* PROOF_ANY_SCALARS_H */

/* abbe: where the fields of a table's header and axis records are, the caps
 * the loader holds their values to, and the counts a record's fields give
 * (docs/table-format.md). Part of model_load.c, which the three loaders
 * compile (model_load.c: 3-axis, five_load.c: five-axis, thermal_load.c: format
 * 1.3): static functions in a header so each loader's translation unit
 * inlines them as it did when they were one file (bench/results.md). Not
 * installed; includes nothing but internal.h. */
#ifndef ABBE_MODEL_LOAD_LAYOUT_H
#define ABBE_MODEL_LOAD_LAYOUT_H

#include "internal.h"
#include "model_load_acsl.h"

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
    /*@ WP_LOOP_POPCOUNT */
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

#endif /* ABBE_MODEL_LOAD_LAYOUT_H */

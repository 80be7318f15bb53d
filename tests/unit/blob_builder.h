/* Test helper: build abbe tables in C, so malformed-table tests can craft any
 * defect (with a correct CRC where the defect is elsewhere). Test code only. */
#ifndef ABBE_TEST_BLOB_BUILDER_H
#define ABBE_TEST_BLOB_BUILDER_H

#include <stddef.h>
#include <stdint.h>

/* Field offsets of docs/table-format.md, for mutation tests. */
#define TB_H_MAGIC 0u
#define TB_H_MAJOR 4u
#define TB_H_MINOR 6u
#define TB_H_TOTAL 8u
#define TB_H_HEADER_SIZE 12u
#define TB_H_AXIS_SIZE 16u
#define TB_H_FEATURES 20u
#define TB_H_REFERENCE 24u
#define TB_H_TOOL 36u
#define TB_H_SQUARENESS 48u
#define TB_H_RESERVED 60u
#define TB_AXIS(j) (64u + 64u * (unsigned)(j))
#define TB_A_MIN 0u
#define TB_A_MAX 4u
#define TB_A_MASK 8u
#define TB_A_DEGREE 9u
#define TB_A_HARMONICS 10u
#define TB_A_PERIOD 12u
#define TB_A_ORIGIN 20u
#define TB_A_BACKLASH 28u
#define TB_A_TAKEUP 32u
#define TB_A_EXPANSION 36u
#define TB_A_THERMAL_OFFSET 40u
#define TB_A_TREF 44u
#define TB_A_COEF_Q 48u
#define TB_A_COEF_F32 52u
#define TB_A_COEF_COUNT 56u
#define TB_A_REVERSAL_ROWS 60u /* format 1.1; bytes 61..63 reserved */

typedef struct {
    int32_t travel_min_nm, travel_max_nm;
    uint8_t term_mask;
    uint8_t trend_degree; /* 255 = none */
    uint8_t harmonics[2];
    int32_t period_nm[2], origin_nm[2];
    int32_t backlash_q8, takeup_nm;
    int32_t expansion_q50, thermal_offset_q16, tref_mdegc;
    const int32_t *coef_q; /* n_basis x n_terms, row-major; f32 array derived from it */
    uint8_t reversal_rows;     /* format 1.1 reversal block (0 = none) ... */
    const int32_t *reversal_q; /* ... its coefficients, 2^-8 nm, after the matrix in both arrays */
} tb_axis_t;

typedef struct {
    uint16_t version_minor; /* 0 = 1 if features has REVERSAL, else 0 */
    uint32_t features;
    int32_t reference_nm[3], tool_nm[3], squareness_q36[3];
    tb_axis_t axis[3];
} tb_table_t;

/* A table whose three axes have travel [0, 500] mm and no terms. */
void tb_init(tb_table_t *t);

/* Write the blob into buf (cap bytes); returns its size, 0 if it does not fit. */
size_t tb_build(const tb_table_t *t, uint8_t *buf, size_t cap);

/* Recompute the CRC after a mutation. */
void tb_fix_crc(uint8_t *buf, size_t total);

void tb_put_u32(uint8_t *p, uint32_t v);
uint32_t tb_get_u32(const uint8_t *p);

#endif

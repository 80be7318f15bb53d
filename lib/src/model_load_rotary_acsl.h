/* abbe: the invariants an accepted five-axis table gives the rotary axis
 * models, as ACSL predicates (comments only: no code), and the contracts WP
 * proves of the rotary section's checks and view (model_load_rotary.h:
 * check_rotary, build_rotary and their helpers; scripts/prove.sh, "wp five
 * loader"). One statement shared by the loader's contracts and the five-axis
 * evaluation harnesses (tests/proofs/eval_five_any.c asserts
 * rotary_ranges_ok of every record it builds, Eva checks it), as
 * model_load_acsl.h is for the 3-axis loader (docs/proofs.md, "WP: loader
 * contracts", "Five-axis: the rotary records"). Not installed. */
#ifndef ABBE_MODEL_LOAD_ROTARY_ACSL_H
#define ABBE_MODEL_LOAD_ROTARY_ACSL_H

#include "abbe/five_axis.h"
#include "model_load_acsl.h"

/* a rotary record's counts as check_rotary accepts them (byte offset of
 * model_load_rotary.h: 21 the harmonics, RA_HARMONICS): 0..8 harmonics. Not
 * the component mask's bits 6 and 7 (byte 20), which check_rotary refuses
 * too: no evaluator reads them (popcount6 and build_rotary's columns read bits
 * 0..5), and Z3 did not prove the bit test's consequence (as record_counts_ok,
 * model_load_acsl.h) */
/*@ predicate rotary_record_counts_ok(uint8_t *rec) =
        rec[21] <= ABBE_ROTARY_MAX_HARMONICS;
 */
/* the two rotary records of table b (after the rotary header at 256 + 64) */
/*@ predicate rotary_table_counts_ok(uint8_t *b) =
        rotary_record_counts_ok(b + 320) && rotary_record_counts_ok(b + 384);
 */
/* the location angles' cap (SQUARENESS_CAP, 2^28 x 2^-36 rad) */
/*@ predicate rotary_angle_ok(integer v) = -268435456 <= v <= 268435456;
 */
/* component c's column absent (0xFF) or one of the six */
/*@ predicate rotary_column_range(abbe_rotary_model_t *ax, integer c) =
        ax->column[c] == 0xFF || ax->column[c] < ABBE_MOTIONS;
 */
/* those of components 0 .. n-1 (spelt out: the provers then need no instantiation) */
/*@ predicate rotary_column_ranges_below(abbe_rotary_model_t *ax, integer n) =
        (n > 0 ==> rotary_column_range(ax, 0)) && (n > 1 ==> rotary_column_range(ax, 1)) &&
        (n > 2 ==> rotary_column_range(ax, 2)) && (n > 3 ==> rotary_column_range(ax, 3)) &&
        (n > 4 ==> rotary_column_range(ax, 4)) && (n > 5 ==> rotary_column_range(ax, 5));
 */
/* the ranges a rotary axis model's evaluators index by (what
 * tests/proofs/eval_five_any.c builds: Eva checks this predicate on each
 * record there): the machine axis, at most six components, 0..8 harmonics, each column absent (0xFF) or one of the six.
 * The location errors are rotary_location_ok (below; in rotary_layout_ok) */
/*@ predicate rotary_ranges_ok(abbe_rotary_model_t *ax) =
        ax->dir <= 2 && ax->n_comp <= ABBE_MOTIONS &&
        ax->harmonics <= ABBE_ROTARY_MAX_HARMONICS &&
        rotary_column_ranges_below(ax, ABBE_MOTIONS);
 */
/* component c's column: its rank among the present components, or 0xFF */
/*@ predicate rotary_column_ok(abbe_rotary_model_t *ax, integer c) =
        mask_bit(ax->comp_mask, c) == 1 ? ax->column[c] == popcount_below(ax->comp_mask, c)
                                        : ax->column[c] == 0xFF;
 */
/* columns 0 .. n-1 (build_rotary's loop) */
/*@ predicate rotary_columns_below(abbe_rotary_model_t *ax, integer n) =
        (n > 0 ==> rotary_column_ok(ax, 0)) && (n > 1 ==> rotary_column_ok(ax, 1)) &&
        (n > 2 ==> rotary_column_ok(ax, 2)) && (n > 3 ==> rotary_column_ok(ax, 3)) &&
        (n > 4 ==> rotary_column_ok(ax, 4)) && (n > 5 ==> rotary_column_ok(ax, 5));
 */
/* the location errors build_rotary keeps of a record turning about dir:
 * none along the axis itself (delta_q8[dir], phi_q36[dir] 0), the tilts and
 * the zero offset within the loader's angle cap (angle_at, SQUARENESS_CAP);
 * the linear location errors have no cap (any int32) */
/*@ predicate rotary_location_ok(abbe_rotary_model_t *ax, integer dir) =
        ax->delta_q8[dir] == 0 && ax->phi_q36[dir] == 0 &&
        rotary_angle_ok(ax->phi_q36[0]) && rotary_angle_ok(ax->phi_q36[1]) &&
        rotary_angle_ok(ax->phi_q36[2]) && rotary_angle_ok(ax->zero_q36);
 */
/* the whole layout build_rotary makes of an accepted record turning about
 * dir: the ranges, n_comp the mask's popcount, each column the component's
 * rank or 0xFF (as eval_five_any.c's builder), no harmonics without
 * components, and the location errors (rotary_location_ok: Z3 does not prove
 * this part, CVC4 does: scripts/prove.sh, "wp five loader") */
/*@ predicate rotary_layout_ok(abbe_rotary_model_t *ax, integer dir) =
        rotary_ranges_ok(ax) && ax->dir == dir &&
        ax->n_comp == popcount_below(ax->comp_mask, ABBE_MOTIONS) &&
        rotary_columns_below(ax, ABBE_MOTIONS) &&
        (ax->n_comp == 0 ==> ax->harmonics == 0) &&
        rotary_location_ok(ax, dir);
 */

/* The loops' annotations (as WP_LOOP_* of model_load_acsl.h): the invariants
 * under ABBE_PROOF_WP, a trivial one in the other Frama-C runs, nothing for a
 * compiler. */
#if defined(ABBE_PROOF_WP)
#define WP_LOOP_ROT_BYTES                                                                  \
    loop invariant wp_rot_bytes: 0 <= i <= count;                                          \
    loop assigns i;                                                                        \
    loop variant count - i;
#define WP_LOOP_ROT_WORDS                                                                  \
    loop invariant wp_rot_words: 0 <= i <= count;                                          \
    loop assigns i;                                                                        \
    loop variant count - i;
#define WP_LOOP_ROT_LEVER                                                                  \
    loop invariant wp_rot_lever: 0 <= k <= 3;                                              \
    loop assigns k, left;                                                                  \
    loop variant 3 - k;
#define WP_LOOP_ROT_COEFS                                                                  \
    loop assigns i;
#define WP_LOOP_ROT_COMPONENTS                                                             \
    loop assigns c, column;                                                                \
    loop variant ABBE_MOTIONS - c;
#define WP_LOOP_ROT_ROWS                                                                   \
    loop assigns row, l1;
#define WP_LOOP_ROT_CATEGORIES                                                             \
    loop invariant wp_rot_cat: 0 <= cat <= RC_CATEGORIES;                                  \
    loop invariant wp_rot_counted: cat > RC_COUNT ==> rotary_table_counts_ok(b);           \
    loop assigns cat;                                                                      \
    loop variant RC_CATEGORIES - cat;
#define WP_LOOP_ROT_RECORDS                                                                \
    loop invariant wp_rot_r: 0 <= r <= ABBE_ROTARY_AXES;                                   \
    loop invariant wp_rot_records: cat == RC_COUNT ==>                                     \
        ((r > 0 ==> rotary_record_counts_ok(b + 320)) && (r > 1 ==> rotary_record_counts_ok(b + 384))); \
    loop assigns r;                                                                        \
    loop variant ABBE_ROTARY_AXES - r;
#define WP_LOOP_ROT_COLUMNS                                                                \
    loop invariant wp_rot_rank: 0 <= c <= ABBE_MOTIONS && column == popcount_below(ax->comp_mask, c) && column <= c; \
    loop invariant wp_rot_columns: rotary_columns_below(ax, c);                            \
    loop invariant wp_rot_column_ranges: rotary_column_ranges_below(ax, c);                \
    loop assigns c, column, ax->column[0 .. ABBE_MOTIONS - 1];                             \
    loop variant ABBE_MOTIONS - c;
#elif defined(__FRAMAC__)
#define WP_LOOP_ROT_BYTES loop invariant \true;
#define WP_LOOP_ROT_WORDS loop invariant \true;
#define WP_LOOP_ROT_LEVER loop invariant \true;
#define WP_LOOP_ROT_COEFS loop invariant \true;
#define WP_LOOP_ROT_COMPONENTS loop invariant \true;
#define WP_LOOP_ROT_ROWS loop invariant \true;
#define WP_LOOP_ROT_CATEGORIES loop invariant \true;
#define WP_LOOP_ROT_RECORDS loop invariant \true;
#define WP_LOOP_ROT_COLUMNS loop invariant \true;
#endif

#if defined(ABBE_PROOF_WP)
/* The contracts WP proves (scripts/prove.sh, "wp five loader"; only there is
 * ABBE_PROOF_WP defined). abbe_u32_to_i32 (a pun through memcpy, internal.h)
 * and i32_to_f32_bits (model_load_checks.h: Z3 did not prove its call's
 * precondition, bit_length's v != 0, from the magnitude's modular negation)
 * are given what WP needs of them (they write nothing), as abbe_ld_u32 in
 * model_load_acsl.h; every other function below is proven. */
/*@ requires \valid_read(p + (0 .. 1));
    assigns \nothing; */
static inline uint16_t abbe_ld_u16(const uint8_t *p);
/*@ assigns \nothing; */
static inline int32_t abbe_u32_to_i32(uint32_t u);
/*@ assigns \nothing; */
static inline int abbe_f32_bits_nonfinite(uint32_t bits);
/*@ assigns \nothing; */
static uint32_t mag_i32(int32_t v);
/*@ assigns \nothing; */
static uint32_t i32_to_f32_bits(int32_t v);
/*@ requires table: \valid_read(b + (0 .. total - 1));
    assigns \nothing; */
static uint32_t coef_word(const uint8_t *b, uint32_t total, uint32_t off, uint32_t i);
/*@ requires cap: cap >= 0;
    assigns \nothing;
    ensures capped: -cap <= \result <= cap; */
static int32_t capped_i32(int32_t v, int32_t cap);

/*@ requires r <= 1;
    assigns \nothing;
    ensures at: \result == b + 320 + 64 * r; */
static const uint8_t *rotary_record(const uint8_t *b, unsigned r);
/*@ requires \valid_read(p + (0 .. count - 1));
    assigns \nothing; */
static int any_nonzero_u8(const uint8_t *p, unsigned count);
/*@ requires count <= 6 && \valid_read(p + (0 .. 4 * count - 1));
    assigns \nothing; */
static int any_above(const uint8_t *p, unsigned count, uint32_t cap);
/*@ requires \valid_read(h + (0 .. 63));
    assigns \nothing; */
static int hh_lever_too_long(const uint8_t *h);
/*@ requires table: \valid_read(b + (0 .. total - 1)) && total >= ABBE_ROTARY_DATA_START + 4;
    requires record: \valid_read(rec + (0 .. 63));
    assigns \nothing;
    ensures counts: cat == 1 && \result == 0 ==> rotary_record_counts_ok(rec); */
static int rotary_record_bad(const uint8_t *b, const uint8_t *rec, uint32_t total, unsigned cat); /* cat 1: RC_COUNT */
/*@ requires table: \valid_read(b + (0 .. total - 1)) && total >= ABBE_ROTARY_DATA_START + 4;
    assigns \nothing;
    ensures counts_ok: \result == ABBE_OK ==> rotary_table_counts_ok(b); */
static abbe_status_t check_rotary(const uint8_t *b, uint32_t total);

/*@ requires \valid(i1) && \valid(i2) && \separated(i1, i2);
    assigns *i1, *i2;
    ensures others: *i1 == (dir == 0 ? 1 : 0) && *i2 == (dir == 2 ? 1 : 2); */
static void others_of(unsigned dir, unsigned *i1, unsigned *i2);
/*@ requires \valid_read(p + (0 .. 3));
    assigns \nothing;
    ensures capped: -1073741823 <= \result <= 1073741823; */
static int32_t geometry_at(const uint8_t *p);
/*@ requires \valid_read(p + (0 .. 3));
    assigns \nothing;
    ensures capped: rotary_angle_ok(\result); */
static int32_t angle_at(const uint8_t *p);
/*@ requires out: \valid(ax);
    requires record: \valid_read(rec + (0 .. 63));
    requires apart: \separated(ax, rec + (0 .. 63));
    requires dir: dir <= 2;
    requires counts: rotary_record_counts_ok(rec);
    assigns *ax;
    ensures layout_ok: rotary_layout_ok(ax, dir); */
static void build_rotary(abbe_rotary_model_t *ax, const uint8_t *b, const uint8_t *rec, unsigned dir);
#endif

#endif /* ABBE_MODEL_LOAD_ROTARY_ACSL_H */

/* abbe: five-axis table-table (trunnion) machines, table format 1.2.
 *
 * A five-axis table is a 3-axis table (the linear axes, evaluated as by
 * abbe/error.h) plus a rotary section: the kinematics (xyzac-trt or
 * xyzbc-trt, LinuxCNC's names), the nominal geometry (C axis centre and the
 * tilt axis' offset from it), the five-axis squareness and, per rotary axis,
 * its ISO 230-1 location errors and the Fourier series of its six error
 * motions (period one turn). docs/table-format.md, "Rotary section (1.2)".
 *
 * The evaluation gives the first-order error of the tool tip relative to the
 * workpiece at joint positions (X, Y, Z, tilt, C): the position error, which
 * a compensator can take out through X, Y, Z, and the orientation error,
 * which it cannot (docs/concepts.md, "Five-axis machines"). Both variants
 * agree with the Python reference (abbe.model.five_axis.tool_error_linear)
 * within the bounds of docs/numerics.md, "Five-axis evaluation".
 *
 * A 3-axis table loads here too (its rotary errors are then zero); a
 * five-axis table is refused by abbe_model_load() (ABBE_E_VERSION_MINOR), so a
 * 3-axis firmware never evaluates half of one. A library built without the
 * format 1.1 reversal blocks (ABBE_NO_REVERSAL) reads no five-axis tables.
 */
#ifndef ABBE_FIVE_AXIS_H
#define ABBE_FIVE_AXIS_H

#include <stddef.h>
#include <stdint.h>

#include "abbe/model.h"

#define ABBE_FEATURE_ROTARY 0x20u /* format 1.2: the rotary section */
#define ABBE_ROTARY_AXES 2        /* the tilt axis (A or B), then the table axis C */
#define ABBE_MOTIONS 6            /* error motion components: X, Y, Z (linear), A, B, C (angular) */
#define ABBE_ROTARY_MAX_HARMONICS 8

/* Kinematics kinds (the rotary header's kind byte). */
#define ABBE_KIN_NONE 0u       /* a 3-axis table */
#define ABBE_KIN_XYZAC_TRT 1u  /* A (about X) carries C (about Z) */
#define ABBE_KIN_XYZBC_TRT 2u  /* B (about Y) carries C */
/* Format 1.4 (docs/table-format.md, "Other kinematic kinds"); a library built
 * with ABBE_NO_FIVE_KINDS (CMake ABBE_WITH_FIVE_KINDS=OFF) refuses them. */
#define ABBE_KIN_XYZBC_HH 3u   /* head-head: C (about Z) in the head carries B (about Y), 5axiskins */
#define ABBE_KIN_XYZBC_HT 4u   /* head-table: B (about Y) in the head, C (about Z) the table, maxkins */
#define ABBE_KIN_XYZAB_TDR 5u  /* dual rotary table: B (about Y) carries A (about X), xyzab-tdr */

/* The kinds this library reads: bit k for ABBE_KIN_* k (CMake ABBE_FIVE_KINDS, a list of
 * kinds; default all, 0x3E). A machine's firmware needs only its own kind: built without a
 * kind, the loader refuses its tables with ABBE_E_KIND and the evaluation carries none of
 * its geometry (flash: bench/results.md, section 11). ABBE_NO_FIVE_KINDS is the mask 0x06
 * (trunnions only, format 1.2: kinds 3-5 are refused by their minor, ABBE_E_VERSION_MINOR). */
#if !defined(ABBE_FIVE_KIND_MASK)
#if defined(ABBE_NO_FIVE_KINDS)
#define ABBE_FIVE_KIND_MASK 0x06u
#else
#define ABBE_FIVE_KIND_MASK 0x3Eu
#endif
#endif
#define ABBE_FIVE_KIND_BUILT(kind) (((unsigned)(ABBE_FIVE_KIND_MASK) >> (kind)) & 1u)

/* One rotary axis: a validated view; fields private. */
typedef struct {
    const uint8_t *coef_q;       /* int32 LE, 2 x harmonics rows by n_comp columns, row-major */
    const uint8_t *coef_f32;     /* float32 twins */
    int32_t delta_q8[3];         /* location: position of the average line, 2^-8 nm (0 along the axis) */
    int32_t phi_q36[3];          /* location: orientation of the line, 2^-36 rad (0 about the axis) */
    int32_t zero_q36;            /* location: angular zero offset, 2^-36 rad */
    uint8_t dir;                 /* machine axis it turns about: 0 X, 1 Y, 2 Z */
    uint8_t comp_mask;           /* bit c: motion component c present */
    uint8_t n_comp;
    uint8_t harmonics;           /* 0..8 */
    uint8_t column[ABBE_MOTIONS];/* column of component c, or 0xFF */
} abbe_rotary_model_t;

/* A loaded five-axis model. Allocate it yourself; fields private. `linear`
 * is a complete 3-axis model of the same table (the first member, so the
 * compensator can hold it). */
typedef struct {
    abbe_model_t linear;
    uint32_t kind;                   /* ABBE_KIN_* */
    int32_t rot_point_nm[3];         /* C axis centre, machine coordinates at zero angles, nm */
    int32_t offset_nm[3];            /* tilt axis point relative to the C centre, nm */
    int32_t tilt_pivot_nm[3];        /* rot_point + offset */
    int32_t squareness_q36[3];       /* five-axis S_xy, S_xz, S_yz, lever from rot_point, 2^-36 rad */
    abbe_rotary_model_t rotary[ABBE_ROTARY_AXES]; /* tilt, table (kinds 3-5: record 0, record 1) */
    int32_t square_ref_nm[3];        /* kinds 3-5: the point the squareness' lever starts at, nm */
    int8_t sign[ABBE_ROTARY_AXES];   /* kinds 3-5: record r turns about +1 / -1 times its machine axis */
    uint8_t slot[ABBE_ROTARY_AXES];  /* kinds 3-5: which angle (alphabetical order) drives record r */
} abbe_five_model_t;

/* Validate a format 1.0 .. 1.2 or 1.4 table and make *model a view of it (rules of
 * abbe_model_load() plus the rotary section's). On failure *model is left
 * untouched. */
abbe_status_t abbe_five_model_load(abbe_five_model_t *model, const void *blob, size_t size);

typedef struct {
    float pos_mm[3];        /* X, Y, Z joint positions, machine coordinates, mm */
    float angle_deg[2];     /* the two rotary joints in alphabetical order (A/B then C; kind 5: A, B), degrees */
    float dir_state[3];     /* linear axes' backlash direction states (abbe_input_f32_t) */
    float temp_c[3];        /* linear axes' temperatures, deg C */
} abbe_five_input_f32_t;

typedef struct {
    float error_um[3];      /* tool tip position error relative to the workpiece, machine frame, um */
    float orient_urad[3];   /* tool orientation error relative to the workpiece (rotation vector), urad */
    uint32_t flags;         /* ABBE_FLAG_* */
} abbe_five_error_f32_t;

typedef struct {
    abbe_nm_t pos_nm[3];
    int32_t angle_udeg[2];  /* tilt, C: micro-degrees (+/-2147 degrees; one turn = 360 000 000, exact) */
    int32_t dir_state_q30[3];
    int32_t temp_mdegc[3];
} abbe_five_input_q_t;

typedef struct {
    abbe_nm_t error_nm[3];  /* position error, nm, saturated */
    int32_t orient_nrad[3]; /* orientation error, nrad, saturated */
    uint32_t flags;
} abbe_five_error_q_t;

/* Tool tip error at one joint position. f32: ABBE_E_INPUT for a NaN/Inf
 * input (then *out is zero), angles beyond +/-2147 degrees are clamped to it
 * (flagged out of travel). Both: ABBE_E_ARG for NULL pointers. */
abbe_status_t abbe_five_error_eval_f32(const abbe_five_model_t *model, const abbe_five_input_f32_t *in,
                                       abbe_five_error_f32_t *out);
abbe_status_t abbe_five_error_eval_q(const abbe_five_model_t *model, const abbe_five_input_q_t *in,
                                     abbe_five_error_q_t *out);

/* Kinematics kind of a loaded model (ABBE_KIN_*). */
uint32_t abbe_five_model_kind(const abbe_five_model_t *model);

/* sizeof(abbe_five_model_t): for bindings that allocate the model themselves
 * (abbe.model.clib), so they need not mirror its private layout. */
size_t abbe_five_model_sizeof(void);

#endif /* ABBE_FIVE_AXIS_H */

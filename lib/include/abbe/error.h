/* abbe: evaluation of the spatial error model (paper Eq. 3, docs/concepts.md).
 *
 * Two variants of the same evaluation read the same model:
 *   _f32  IEEE single precision (FPU targets). Positions in mm, errors in um.
 *   _q    fixed point, integer only (no FPU). Positions and errors in nm.
 * Both agree with the float64 Python reference within the bound derived in
 * docs/numerics.md (2 nm for realistic tables). Run time depends only on the
 * table's shape, never on the input values. Evaluation is stateless; the
 * backlash direction state is an input (abbe_comp_t tracks it for you); it
 * multiplies the axis' reversal, constant (B) or position dependent (format
 * 1.1 reversal block, abbe_reversal_eval_*).
 */
#ifndef ABBE_ERROR_H
#define ABBE_ERROR_H

#include <stddef.h>
#include <stdint.h>

#include "abbe/model.h"

/* C linkage for C++ callers (firmware in C++ links the C library). */
#ifdef __cplusplus
extern "C" {
#endif

/* Result flags (also reported by the compensator). */
#define ABBE_FLAG_OUT_OF_TRAVEL 0x0001u /* a position was outside the table's travel: end value held */
#define ABBE_FLAG_SATURATED 0x0002u     /* fixed point: a value hit its int32 limit */
/* A batch point (or, in the compensator, a cycle) whose input was NaN/Inf;
 * the compensator also sets it for input marked not fresh. */
#define ABBE_FLAG_INPUT_INVALID 0x0200u

/* Fixed-point direction state: Q30, -2^30 = moving -, +2^30 = moving +. */
#define ABBE_DIR_Q30_ONE ((int32_t)1 << 30)

typedef struct {
    float pos_mm[ABBE_AXES];     /* axis positions, machine coordinates, mm */
    float dir_state[ABBE_AXES];  /* backlash direction state, clamped to [-1, 1]; ignored without BACKLASH */
    float temp_c[ABBE_AXES];     /* axis temperatures, deg C; ignored without THERMAL */
} abbe_input_f32_t;

typedef struct {
    float error_um[ABBE_AXES];   /* dX, dY, dZ: tool relative to workpiece, um */
    uint32_t flags;              /* ABBE_FLAG_* */
} abbe_error_f32_t;

typedef struct {
    abbe_nm_t pos_nm[ABBE_AXES];     /* axis positions, machine coordinates, nm */
    int32_t dir_state_q30[ABBE_AXES];/* backlash direction state, Q30, clamped to [-2^30, 2^30] */
    int32_t temp_mdegc[ABBE_AXES];   /* axis temperatures, milli-degrees C */
} abbe_input_q_t;

typedef struct {
    abbe_nm_t error_nm[ABBE_AXES];   /* dX, dY, dZ, nm, saturated to int32 */
    uint32_t flags;                  /* ABBE_FLAG_* */
} abbe_error_q_t;

/* Spatial error at one machine position, single precision.
 * Returns ABBE_OK; ABBE_E_ARG for NULL pointers; ABBE_E_INPUT if a position
 * (or, where the table uses them, a temperature or direction state) is NaN or
 * infinite, or a temperature is beyond +/-10^6 deg C (no sensor reports it;
 * alpha * dT would overflow), in which case *out holds zeros. Positions beyond +/-2147 mm are
 * clamped to it (and flagged out of travel). */
abbe_status_t abbe_error_eval_f32(const abbe_model_t *model, const abbe_input_f32_t *in,
                                  abbe_error_f32_t *out);

/* Spatial error at one machine position, fixed point. Returns ABBE_OK or
 * ABBE_E_ARG (NULL pointers).
 * Saturation is reported in out->flags, never by an in-band value. */
abbe_status_t abbe_error_eval_q(const abbe_model_t *model, const abbe_input_q_t *in,
                                abbe_error_q_t *out);

/* n points in one call (hosts, simulation, diagnosis): out[i] is what
 * abbe_error_eval_f32(model, &in[i], &out[i]) gives, except that a point with
 * NaN/Inf input has zero errors and flags ABBE_FLAG_INPUT_INVALID; the other
 * points are evaluated all the same. Returns ABBE_OK, ABBE_E_INPUT if any
 * point was invalid, ABBE_E_ARG for a NULL model, or NULL arrays with n > 0. */
abbe_status_t abbe_error_eval_batch_f32(const abbe_model_t *model, size_t n, const abbe_input_f32_t *in,
                                        abbe_error_f32_t *out);

/* n points, fixed point: out[i] is what abbe_error_eval_q(model, &in[i],
 * &out[i]) gives. Returns ABBE_OK, or ABBE_E_ARG for a NULL model, or NULL
 * arrays with n > 0. */
abbe_status_t abbe_error_eval_batch_q(const abbe_model_t *model, size_t n, const abbe_input_q_t *in,
                                      abbe_error_q_t *out);

/* One fitted term d_i(j) or eps_ji at axis position pos, without the extra
 * (backlash, thermal) terms. Linear terms in um (f32) / pm (q), angular terms
 * in urad (f32) / prad (q). An absent term evaluates to 0.
 * Returns ABBE_E_ARG for NULL pointers or axis/term out of range,
 * ABBE_E_INPUT for a NaN position (f32). */
abbe_status_t abbe_term_eval_f32(const abbe_model_t *model, unsigned axis, unsigned term,
                                 float pos_mm, float *value);
abbe_status_t abbe_term_eval_q(const abbe_model_t *model, unsigned axis, unsigned term,
                               abbe_nm_t pos_nm, int32_t *value_pm_or_prad);

/* The total reversal R(p) = B + sum_k r_k T_k(u) of an axis' own positioning
 * term at axis position pos: its backlash reversal B plus its reversal block
 * (format 1.1; none: B alone), the block at the position clamped to the
 * travel. The spatial error adds s R(p) / 2 to that term (s: the direction
 * state), so this is what an ISO 230-2 bidirectional test of the axis sees as
 * its reversal. um (f32) / pm (q, saturated to int32); 0 for a table without
 * BACKLASH. Returns ABBE_E_ARG for NULL pointers or an axis out of range,
 * ABBE_E_INPUT for a NaN/Inf position (f32). */
abbe_status_t abbe_reversal_eval_f32(const abbe_model_t *model, unsigned axis, float pos_mm, float *value_um);
abbe_status_t abbe_reversal_eval_q(const abbe_model_t *model, unsigned axis, abbe_nm_t pos_nm, int32_t *value_pm);

#ifdef __cplusplus
} /* extern "C" */
#endif

#endif /* ABBE_ERROR_H */

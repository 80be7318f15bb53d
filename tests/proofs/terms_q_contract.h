/* The contract of the fixed-point term kernel (terms_q.c, terms_sparse_q.c)
 * the any-layout proofs use: terms_q_any.c proves it (Eva checks each
 * postcondition at the kernel's return, for any layout within the loader's
 * invariants, any offset d and the coefficient box of any_layout.h);
 * eval_q_any_layout.c runs the kernel as this contract
 * (-eva-use-spec abbe_axis_terms_q), checking the preconditions at each call.
 * The postconditions are the term ranges assemble_q relies on (eval_q.c):
 * a linear term within +/-(2^30 + 16) (2^-6 nm: +/-16.8 mm), an angular one
 * within +/-(2^27 + 2) (2^-35 rad: +/-3.9 mrad). Those are the ranges for
 * every table the loader accepts: the L1 caps (sum |c| <= 2^32 linear, 2^28
 * angular) times the basis rows' bound 2^30 + 16 (hypotheses cheb_rows and
 * sincos_range: the Chebyshev rows reach 2^30 + 3, the rotated harmonics
 * 2^30 + 11), WP-proven in tests/proofs/terms_q_l1.c. The precondition
 * 'layout' is the shared predicate of the loader's contract (axis_ranges_ok,
 * lib/src/model_load_acsl.h). (Until the L1 proof
 * they were +/-2^30 and +/-2^27, which the box of terms_q_any keeps but an
 * accepted table's coefficients can exceed by a few LSB.) */
#ifndef PROOF_TERMS_Q_CONTRACT_H
#define PROOF_TERMS_Q_CONTRACT_H

#include "internal.h"
#include "model_load_acsl.h"

/* requires layout: the predicate the 3-axis loader's build_axis ensures
 * (lib/src/model_load_acsl.h: axis_layout_ok implies axis_ranges_ok; WP,
 * docs/proofs.md "WP: loader contracts"): the counts' ranges (n_terms <= 6,
 * trend_rows <= 8, harmonics <= 8, n_basis <= 40, reversal_rows <= 8,
 * cheb_shift <= 31) */
/*@ requires layout: axis_ranges_ok(ax);
    requires coefficients: ax->n_basis * ax->n_terms == 0 ||
                           \valid_read(ax->coef_q + (0 .. 4 * ax->n_basis * ax->n_terms - 1));
    requires out: \valid(value + (0 .. 5));
    assigns value[0 .. 5] \from d, ax->coef_q[0 .. 4 * 240 - 1], ax->travel_min_nm, ax->cheb_mul,
        ax->cheb_shift, ax->freq[0 .. 1], ax->phase_min[0 .. 1], ax->n_terms, ax->trend_rows,
        ax->harmonics[0 .. 1], ax->n_basis, ax->column[0 .. 5];
    ensures init: \initialized(value + (0 .. 5));
    ensures lin_x: -0x40000010 <= value[0] <= 0x40000010;
    ensures lin_y: -0x40000010 <= value[1] <= 0x40000010;
    ensures lin_z: -0x40000010 <= value[2] <= 0x40000010;
    ensures ang_x: -0x8000002 <= value[3] <= 0x8000002;
    ensures ang_y: -0x8000002 <= value[4] <= 0x8000002;
    ensures ang_z: -0x8000002 <= value[5] <= 0x8000002;
 */
void abbe_axis_terms_q(const abbe_axis_model_t *ax, uint32_t d, int32_t value[ABBE_TERMS]);

#endif /* PROOF_TERMS_Q_CONTRACT_H */

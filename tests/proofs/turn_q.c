/* WP proof of the bound of the trunnion table axis' angle sum turned by the
 * tilt (five_eval_q.c add_rotary_q: the assertion 'turned_w'; docs/proofs.md,
 * "Five-axis: the loader's caps"). The two turned components are
 *   w_j' = rot_q30(ct, wj, st, wl) = (ct wj - st wl + 2^29) >> 30,
 *   w_l' = rot_q30(st, wj, -ct, wl) = (st wj + ct wl + 2^29) >> 30,
 * i.e. (c x + s y + 2^29) >> 30 with (c, s) = (ct, -st) or (st, ct), both of
 * the norm of abbe_sincos_q30's pair, and (x, y) = (wj, wl). turn_sum below
 * is that sum before the shift; WP proves (Why3 + Z3) that, given
 *   - |c|, |s| <= 2^30 and c^2 + s^2 <= 2^60 + 2^33 (the hypotheses
 *     sincos_range and sincos_norm of tests/proofs/hypotheses.c, every phase),
 *   - x^2 + y^2 <= 5 x 2^58 + 2^35 (the assertion 'turn_vector' before the
 *     turn, which Eva proves in every harness: the table's sums within
 *     2^30 + 8 and 2^29 + 8 at the loader's caps),
 * no int64 operation overflows and the sum is within 2^29 +/- 9 x 2^57, by
 * Lagrange's identity (c x + s y)^2 + (c y - s x)^2 = (c^2 + s^2)(x^2 + y^2).
 * The shift (Eva, PROOF_EVA_SHIFTS, as terms_q_l1.c): within +/-9 x 2^27, the
 * bound of 'turned_w'. Not compiled into the library. */
#include <stdint.h>

#define NORM_MAX 0x1000000200000000 /* 2^60 + 2^33: sincos_norm */
#define VECTOR_MAX 0x1400000800000000 /* 5 x 2^58 + 2^35: turn_vector */
#define TURN_MAX 0x1200000000000000 /* 9 x 2^57 */

/* (c x + s y)^2 <= (c^2 + s^2)(x^2 + y^2): each step a function of its own, so
 * that Z3 sees quantifier-free nonlinear goals */
/*@ assigns \nothing;
    ensures (c * x + s * y) * (c * x + s * y) <= (c * c + s * s) * (x * x + y * y);
 */
static void cauchy(int32_t c, int32_t s, int32_t x, int32_t y)
{
    /*@ assert lagrange: (c * c + s * s) * (x * x + y * y) ==
                         (c * x + s * y) * (c * x + s * y) + (c * y - s * x) * (c * y - s * x); */
}

/*@ requires 0 <= a <= NORM_MAX && 0 <= b <= VECTOR_MAX;
    assigns \nothing;
    ensures a * b <= NORM_MAX * VECTOR_MAX;
 */
static void monotone(int64_t a, int64_t b)
{
}

/*@ requires z * z <= TURN_MAX * TURN_MAX;
    assigns \nothing;
    ensures -TURN_MAX <= z <= TURN_MAX;
 */
static void root(int64_t z)
{
}

/*@ requires -0x40000000 <= c <= 0x40000000 && -0x40000000 <= s <= 0x40000000;
    requires sincos_norm: c * c + s * s <= NORM_MAX;
    requires turn_vector: x * x + y * y <= VECTOR_MAX;
    assigns \nothing;
    ensures turn: -TURN_MAX <= \result - 0x20000000 <= TURN_MAX;
 */
int64_t turn_sum(int32_t c, int32_t s, int32_t x, int32_t y)
{
    cauchy(c, s, x, y);
    monotone((int64_t)c * c + (int64_t)s * s, (int64_t)x * x + (int64_t)y * y);
    const int64_t z = (int64_t)c * x + (int64_t)s * y;
    root(z);
    return z + 0x20000000; /* abbe_smlal(abbe_smlal(2^29, c, x), s, y) */
}

/* rot_q30's final shift; its postcondition is Eva's (WP's model of a signed
 * >> is not one Z3 decides; PROOF_EVA_SHIFTS below) */
/*@ requires 0x20000000 - TURN_MAX <= acc <= 0x20000000 + TURN_MAX;
    assigns \nothing;
    ensures turned_shift: -0x48000000 <= \result <= 0x48000000;
 */
static int32_t turned(int64_t acc)
{
    return (int32_t)(acc >> 30);
}

#ifdef PROOF_EVA_SHIFTS
#include "__fc_builtin.h"

int main(void)
{
    volatile int32_t sink = turned(Frama_C_long_interval(0x20000000L - TURN_MAX, 0x20000000L + TURN_MAX));
    (void)sink;
    return 0;
}
#endif

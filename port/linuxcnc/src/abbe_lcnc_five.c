/* abbe LinuxCNC port, five-axis mode: which frame the external offsets are
 * added in (the kinematics in force), and the correction turned from the
 * joint frame into it (include/abbe_lcnc.h, docs/linuxcnc.md "Five-axis
 * machines"). Called by abbe_lcnc_step() every servo period.
 * C99, no heap, no I/O, no libm. */
#include "abbe_lcnc_five.h"
#include "abbe_lcnc_units.h"

/* An angle in degrees reduced to [-180, 180] (the model is periodic in one
 * turn; the q variant takes +/-2147 degrees). a must be finite. */
double abbe_lcnc_reduce_deg(double a)
{
    double turns = a / 360.0;
    if (turns > 9e15 || turns < -9e15) {
        return 0.0; /* beyond double's integers: no fraction of a turn is left */
    }
    return a - 360.0 * (double)round_i64(turns);
}

/* sin and cos of an angle in [-180, 180] degrees, double precision, no libm:
 * the nearest quarter turn q is taken out exactly (90 q is exact in double),
 * the rest r in [-45, 45] degrees goes through Taylor series to x^17 / x^18
 * (truncation below 1e-18 at pi/4). The library's sin/cos are float or Q30 of
 * an integer phase: the offsets' rotation is done in the port's double. */
static void sincos_deg(double deg, double *s_out, double *c_out)
{
    int64_t q = round_i64(deg / 90.0);
    double x = (deg - 90.0 * (double)q) * 0.017453292519943295769; /* pi / 180 */
    double z = x * x;
    double s = 1.0, c = 1.0;
    for (int k = 17; k >= 3; k -= 2) { /* 1 - z/(2*3) (1 - z/(4*5) (...)) */
        s = 1.0 - z / (double)((k - 1) * k) * s;
    }
    for (int k = 18; k >= 2; k -= 2) {
        c = 1.0 - z / (double)((k - 1) * k) * c;
    }
    s *= x;
    switch ((int)(q & 3)) { /* two's complement: q & 3 is q mod 4 for negative q too */
    case 1: *s_out = c; *c_out = -s; break;
    case 2: *s_out = -s; *c_out = -c; break;
    case 3: *s_out = -c; *c_out = s; break;
    default: *s_out = s; *c_out = c; break;
    }
}

/* The correction v (joint frame) as a world offset under the tool-centre-point
 * kinematics (format 1.4's kinds: 5axiskins, maxkins, xyzab_tdr_kins below; trt:
 * Rz(c)^T R_tilt(t)^T v, R_tilt = Rx (xyzac) or Ry (xyzbc); trtfuncs.c's
 * inverse kinematics moves the joints by R_tilt(t) Rz(c) e for a world change e. */
void abbe_lcnc_joints_to_workpiece(uint32_t kind, const double angle_deg[ABBE_ROTARY_AXES], const double v[3],
                                   double w[3])
{
    double st, ct, sc, cc, u[3];
    sincos_deg(angle_deg[0], &st, &ct);
    sincos_deg(angle_deg[1], &sc, &cc);
    if (kind == ABBE_KIN_XYZBC_HH) { /* 5axiskins: world = joints + f(B, C), the offsets are the joints' */
        w[0] = v[0];
        w[1] = v[1];
        w[2] = v[2];
        return;
    }
    if (kind == ABBE_KIN_XYZBC_HT) { /* maxkins: j = Rz(-C) P - h(B), so P moves by Rz(C) v (C: angle 1) */
        w[0] = cc * v[0] - sc * v[1];
        w[1] = sc * v[0] + cc * v[1];
        w[2] = v[2];
        return;
    }
    if (kind == ABBE_KIN_XYZAB_TDR) { /* xyzab_tdr_kins: j = Ry(B)^T Rx(A)^T p + ..., so Rx(A) Ry(B) v */
        u[0] = sc * v[2] + cc * v[0]; /* Ry(B), B: angle 1 */
        u[1] = v[1];
        u[2] = cc * v[2] - sc * v[0];
        w[0] = u[0]; /* Rx(A), A: angle 0 */
        w[1] = ct * u[1] - st * u[2];
        w[2] = st * u[1] + ct * u[2];
        return;
    }
    if (kind == ABBE_KIN_XYZBC_TRT) { /* Ry(t)^T */
        u[0] = ct * v[0] - st * v[2];
        u[1] = v[1];
        u[2] = st * v[0] + ct * v[2];
    } else { /* Rx(t)^T */
        u[0] = v[0];
        u[1] = ct * v[1] + st * v[2];
        u[2] = -st * v[1] + ct * v[2];
    }
    w[0] = cc * u[0] + sc * u[1]; /* Rz(c)^T */
    w[1] = -sc * u[0] + cc * u[1];
    w[2] = u[2];
}

/* ABBE_LCNC_FRAME_* of the kinematics in force. */
int32_t abbe_lcnc_frame_of(const abbe_lcnc_t *port, double kinstype)
{
    if (port->kind == ABBE_KIN_NONE) {
        return ABBE_LCNC_FRAME_JOINTS;
    }
    if (!finite_d(kinstype) || kinstype > 2e9 || kinstype < -2e9) {
        return ABBE_LCNC_FRAME_UNKNOWN;
    }
    int64_t k = round_i64(kinstype); /* motion.switchkins-type is a float pin carrying an integer */
    if (k == port->kins_tcp) {
        return ABBE_LCNC_FRAME_WORKPIECE;
    }
    return k == port->kins_identity ? ABBE_LCNC_FRAME_JOINTS : ABBE_LCNC_FRAME_UNKNOWN;
}

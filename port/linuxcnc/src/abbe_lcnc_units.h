/* abbe LinuxCNC port, private: the number checks and roundings every part of
 * the port's C uses (abbe_lcnc_setup.c, abbe_lcnc.c, abbe_lcnc_five.c).
 * Static inline so that splitting the port into files left the servo
 * period's code as it was (each file gets its own copy, inlined). */
#ifndef ABBE_LCNC_UNITS_H
#define ABBE_LCNC_UNITS_H

#include <float.h>
#include <stdint.h>

#define NM_PER_MM 1e6

static inline int finite_d(double x)
{
    return x >= -DBL_MAX && x <= DBL_MAX; /* false for NaN and +/-Inf */
}

/* Round to nearest (halves away from zero); x must be finite and in range. */
static inline int64_t round_i64(double x)
{
    return (int64_t)(x >= 0.0 ? x + 0.5 : x - 0.5);
}

#endif /* ABBE_LCNC_UNITS_H */

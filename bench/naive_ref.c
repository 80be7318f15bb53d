/* Naive reference evaluation (see naive_ref.h). Not part of the library. */
#include "naive_ref.h"

#include <math.h>
#include <string.h>

static uint32_t rd_u32(const uint8_t *p)
{
    return (uint32_t)p[0] | ((uint32_t)p[1] << 8) | ((uint32_t)p[2] << 16) |
           ((uint32_t)p[3] << 24);
}

static int32_t rd_i32(const uint8_t *p)
{
    uint32_t u = rd_u32(p);
    int32_t v;
    memcpy(&v, &u, sizeof v);
    return v;
}

#define NAIVE_PI 3.14159265358979323846
#define LIN_UM (1.0 / 256.0 / 1000.0)        /* 2^-8 nm in um */
#define ANG_URAD (1.0e6 / 68719476736.0)     /* 2^-36 rad in urad */

int naive_load(naive_model_t *m, const uint8_t *b, size_t size)
{
    if (size < 260 || memcmp(b, "ABBE", 4) != 0) {
        return -1;
    }
    memset(m, 0, sizeof *m);
    m->features = rd_u32(b + 20);
    for (int i = 0; i < 3; i++) {
        m->ref_mm[i] = rd_i32(b + 24 + 4 * i) * 1e-6;
        m->tool_mm[i] = rd_i32(b + 36 + 4 * i) * 1e-6;
    }
    m->s_xy_urad = rd_i32(b + 48) * ANG_URAD;
    m->s_xz_urad = rd_i32(b + 52) * ANG_URAD;
    m->s_yz_urad = rd_i32(b + 56) * ANG_URAD;
    for (int j = 0; j < 3; j++) {
        const uint8_t *r = b + 64 + 64 * j;
        naive_axis_t *a = &m->axis[j];
        unsigned mask = r[8];
        a->travel_min_mm = rd_i32(r + 0) * 1e-6;
        a->travel_max_mm = rd_i32(r + 4) * 1e-6;
        a->trend_rows = r[9] == 255 ? 0 : r[9] + 1;
        a->harmonics[0] = r[10];
        a->harmonics[1] = r[11];
        for (int k = 0; k < 2; k++) {
            a->period_mm[k] = rd_i32(r + 12 + 4 * k) * 1e-6;
            a->origin_mm[k] = rd_i32(r + 20 + 4 * k) * 1e-6;
        }
        a->backlash_um = rd_i32(r + 28) * LIN_UM;
        a->expansion_per_k = rd_i32(r + 36) * pow(2.0, -50) * 1000.0;
        a->offset_um_per_k = rd_i32(r + 40) / 65536.0;
        a->tref_c = rd_i32(r + 44) * 1e-3;
        int n_terms = 0;
        for (int t = 0; t < 6; t++) {
            n_terms += (mask >> t) & 1;
        }
        int n_basis = a->trend_rows + 2 * a->harmonics[0] + 2 * a->harmonics[1];
        if (n_basis > NAIVE_MAX_BASIS) {
            return -1;
        }
        uint32_t off = rd_u32(r + 48);
        int col = 0;
        for (int t = 0; t < 6; t++) {
            if (!((mask >> t) & 1)) {
                continue;
            }
            a->present[t] = 1;
            for (int row = 0; row < n_basis; row++) {
                int32_t c = rd_i32(b + off + 4u * (uint32_t)(row * n_terms + col));
                a->coef[t][row] = c * (t < 3 ? LIN_UM : ANG_URAD);
            }
            col++;
        }
        a->reversal_rows = r[60];
        if (a->reversal_rows > 8) {
            return -1;
        }
        for (int k = 0; k < a->reversal_rows; k++) {
            a->reversal_um[k] = rd_i32(b + off + 4u * (uint32_t)(n_basis * n_terms + k)) * LIN_UM;
        }
    }
    return 0;
}

/* The total reversal B + sum_k r_k T_k(u) at p (mm), the block clamped; T_k = cos(k acos u). */
static double reversal_value(const naive_axis_t *a, double p)
{
    double v = a->backlash_um;
    if (a->reversal_rows > 0) {
        p = p < a->travel_min_mm ? a->travel_min_mm : (p > a->travel_max_mm ? a->travel_max_mm : p);
        double u = (2.0 * p - a->travel_min_mm - a->travel_max_mm) / (a->travel_max_mm - a->travel_min_mm);
        u = u > 1.0 ? 1.0 : (u < -1.0 ? -1.0 : u);
        for (int k = 0; k < a->reversal_rows; k++) {
            v += a->reversal_um[k] * cos(k * acos(u));
        }
    }
    return v;
}

/* One term of one axis at position p (mm): trend + Fourier, clamped. */
static double term_value(const naive_axis_t *a, int t, double p)
{
    if (!a->present[t]) {
        return 0.0;
    }
    if (p < a->travel_min_mm) {
        p = a->travel_min_mm;
    }
    if (p > a->travel_max_mm) {
        p = a->travel_max_mm;
    }
    const double *c = a->coef[t];
    double v = 0.0;
    int row = 0;
    if (a->trend_rows > 0) {
        double u = (2.0 * p - a->travel_min_mm - a->travel_max_mm) /
                   (a->travel_max_mm - a->travel_min_mm);
        double t0 = 1.0, t1 = u;
        v += c[row++] * t0;
        for (int k = 1; k < a->trend_rows; k++) {
            v += c[row++] * t1;
            double t2 = 2.0 * u * t1 - t0;
            t0 = t1;
            t1 = t2;
        }
    }
    for (int blk = 0; blk < 2; blk++) {
        if (a->harmonics[blk] == 0) {
            continue;
        }
        double phi = 2.0 * NAIVE_PI * (p - a->origin_mm[blk]) / a->period_mm[blk];
        for (int n = 1; n <= a->harmonics[blk]; n++) {
            v += c[row++] * sin(n * phi);
            v += c[row++] * cos(n * phi);
        }
    }
    return v;
}

void naive_eval(const naive_model_t *m, const double pos_mm[3], const double dir[3],
                const double temp_c[3], double err_um[3])
{
    double v[3][6];
    double lev[3];
    for (int j = 0; j < 3; j++) {
        const naive_axis_t *a = &m->axis[j];
        for (int t = 0; t < 6; t++) {
            v[j][t] = term_value(a, t, pos_mm[j]);
        }
        lev[j] = pos_mm[j] - m->ref_mm[j];
        if (m->features & 0x4u) {
            double s = dir[j] > 1.0 ? 1.0 : (dir[j] < -1.0 ? -1.0 : dir[j]);
            v[j][j] += s * reversal_value(a, pos_mm[j]) / 2.0;
        }
        if (m->features & 0x8u) {
            double dt = temp_c[j] - a->tref_c;
            v[j][j] += a->expansion_per_k * dt * lev[j] * 1000.0 + a->offset_um_per_k * dt;
        }
    }
    const double *X = v[0], *Y = v[1], *Z = v[2];
    const double x = lev[0], y = lev[1], z = lev[2];
    const double *t = m->tool_mm;
    /* mm * urad = nm: the lever terms are divided by 1000 to give um. */
    double dx = -X[0] - Y[0] + Z[0] +
                (-y * (X[5] + Y[5]) - z * (X[4] + Y[4]) + y * m->s_xy_urad - z * m->s_xz_urad +
                 t[1] * (X[5] + Y[5] - Z[5]) + t[2] * (Z[4] - X[4] - Y[4])) / 1000.0;
    double dy = -X[1] - Y[1] + Z[1] +
                (x * X[5] + z * (X[3] + Y[3]) - z * m->s_yz_urad +
                 t[0] * (Z[5] - X[5] - Y[5]) + t[2] * (X[3] + Y[3] - Z[3])) / 1000.0;
    double dz = -X[2] - Y[2] + Z[2] +
                (-x * X[4] + y * (X[3] + Y[3]) +
                 t[0] * (X[4] + Y[4] - Z[4]) + t[1] * (Z[3] - X[3] - Y[3])) / 1000.0;
    err_um[0] = dx;
    err_um[1] = dy;
    err_um[2] = dz;
}

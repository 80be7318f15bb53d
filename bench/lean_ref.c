/* Lean reference evaluator (see lean_ref.h). Benchmark code, not the library. */
#include "lean_ref.h"

#include <string.h>

static uint32_t rd_u32(const uint8_t *p)
{
    return (uint32_t)p[0] | ((uint32_t)p[1] << 8) | ((uint32_t)p[2] << 16) | ((uint32_t)p[3] << 24);
}

static int32_t rd_i32(const uint8_t *p)
{
    uint32_t u = rd_u32(p);
    int32_t v;
    memcpy(&v, &u, sizeof v);
    return v;
}

int lean_load(lean_model_t *m, const uint8_t *b, size_t size)
{
    if (size < 260 || memcmp(b, "ABBE", 4) != 0) {
        return -1;
    }
    memset(m, 0, sizeof *m);
    for (int i = 0; i < 3; i++) {
        m->ref_mm[i] = (float)rd_i32(b + 24 + 4 * i) * 1e-6f;
    }
    const float urad = 1.0e6f / 68719476736.0f; /* 2^-36 rad */
    m->s_xy = (float)rd_i32(b + 48) * urad;
    m->s_xz = (float)rd_i32(b + 52) * urad;
    m->s_yz = (float)rd_i32(b + 56) * urad;
    for (int j = 0; j < 3; j++) {
        const uint8_t *r = b + 64 + 64 * j;
        lean_axis_t *a = &m->axis[j];
        float lo = (float)rd_i32(r) * 1e-6f, hi = (float)rd_i32(r + 4) * 1e-6f;
        a->min_mm = lo;
        a->mid_mm = 0.5f * (lo + hi);
        a->inv_half_span = 2.0f / (hi - lo);
        a->trend_rows = r[9] == 255 ? 0 : r[9] + 1;
        for (int k = 0; k < 2; k++) {
            a->harmonics[k] = r[10 + k];
            int32_t period = rd_i32(r + 12 + 4 * k);
            a->period_turns_per_mm[k] = period > 0 ? 1.0e6f / (float)period : 0.0f;
            a->origin_mm[k] = (float)rd_i32(r + 20 + 4 * k) * 1e-6f;
        }
        a->coef = (const float *)(const void *)(b + rd_u32(r + 52));
        int col = 0;
        for (int t = 0; t < 6; t++) {
            if ((r[8] >> t) & 1) {
                a->term_of_col[col] = t;
                a->scale[col] = t < 3 ? 1.0f / 256000.0f : urad; /* 2^-8 nm in um; 2^-36 rad in urad */
                col++;
            }
        }
        a->n_terms = col;
    }
    return 0;
}

/* sin and cos of 2 pi x (x in turns), float reduction to the nearest quarter. */
static void lean_sincos(float turns, float *s_out, float *c_out)
{
    float q = turns * 4.0f;
    int k = (int)(q >= 0.0f ? q + 0.5f : q - 0.5f);
    float u = (q - (float)k) * 1.5707963267948966f; /* |u| <= pi/4 */
    float z = u * u;
    float s = u * (1.0f + z * (-0.16666667f + z * (0.0083333310f + z * -0.00019840874f)));
    float c = 1.0f + z * (-0.5f + z * (0.041666638f + z * (-0.0013888378f + z * 2.4760495e-05f)));
    switch (k & 3) {
    case 0: *s_out = s; *c_out = c; break;
    case 1: *s_out = c; *c_out = -s; break;
    case 2: *s_out = -s; *c_out = -c; break;
    default: *s_out = -c; *c_out = s; break;
    }
}

/* Six terms (every axis of a fitted table): six accumulators in registers. */
static void lean_axis6(const lean_axis_t *a, float p, float v[6])
{
    const float *r = a->coef;
    float a0 = 0, a1 = 0, a2 = 0, a3 = 0, a4 = 0, a5 = 0;
#define LEAN_ROW(b)                                                                        \
    do {                                                                                   \
        const float b_ = (b);                                                              \
        a0 += r[0] * b_; a1 += r[1] * b_; a2 += r[2] * b_;                                 \
        a3 += r[3] * b_; a4 += r[4] * b_; a5 += r[5] * b_;                                 \
        r += 6;                                                                            \
    } while (0)
    if (a->trend_rows > 0) {
        float u = (p - a->mid_mm) * a->inv_half_span, t0 = 1.0f, t1 = u;
        LEAN_ROW(1.0f);
        if (a->trend_rows > 1) {
            LEAN_ROW(u);
        }
        for (int k = 2; k < a->trend_rows; k++) {
            float t = 2.0f * u * t1 - t0;
            t0 = t1;
            t1 = t;
            LEAN_ROW(t);
        }
    }
    for (int b = 0; b < 2; b++) {
        if (a->harmonics[b] == 0) {
            continue;
        }
        float s1, c1;
        lean_sincos((p - a->origin_mm[b]) * a->period_turns_per_mm[b], &s1, &c1);
        float s = s1, c = c1;
        for (int h = 1;; h++) {
            LEAN_ROW(s);
            LEAN_ROW(c);
            if (h == a->harmonics[b]) {
                break;
            }
            float sn = s * c1 + c * s1;
            c = c * c1 - s * s1;
            s = sn;
        }
    }
#undef LEAN_ROW
    v[0] = a0 * a->scale[0];
    v[1] = a1 * a->scale[1];
    v[2] = a2 * a->scale[2];
    v[3] = a3 * a->scale[3];
    v[4] = a4 * a->scale[4];
    v[5] = a5 * a->scale[5];
}

static void lean_axis(const lean_axis_t *a, float p, float v[6])
{
    if (a->n_terms == 6) {
        lean_axis6(a, p, v);
        return;
    }
    float acc[6] = {0, 0, 0, 0, 0, 0};
    const int n = a->n_terms;
    const float *row = a->coef;
    if (a->trend_rows > 0) {
        float u = (p - a->mid_mm) * a->inv_half_span, t0 = 1.0f, t1 = u;
        for (int k = 0; k < a->trend_rows; k++) {
            float t = k == 0 ? 1.0f : (k == 1 ? u : 2.0f * u * t1 - t0);
            if (k >= 2) {
                t0 = t1;
                t1 = t;
            }
            for (int c = 0; c < n; c++) {
                acc[c] += row[c] * t;
            }
            row += n;
        }
    }
    for (int b = 0; b < 2; b++) {
        if (a->harmonics[b] == 0) {
            continue;
        }
        float s1, c1;
        lean_sincos((p - a->origin_mm[b]) * a->period_turns_per_mm[b], &s1, &c1);
        float s = s1, c = c1;
        for (int h = 1; h <= a->harmonics[b]; h++) {
            for (int col = 0; col < n; col++) {
                acc[col] += row[col] * s + row[n + col] * c;
            }
            row += 2 * n;
            float sn = s * c1 + c * s1;
            c = c * c1 - s * s1;
            s = sn;
        }
    }
    for (int t = 0; t < 6; t++) {
        v[t] = 0.0f;
    }
    for (int col = 0; col < n; col++) {
        v[a->term_of_col[col]] = acc[col] * a->scale[col];
    }
}

void lean_eval(const lean_model_t *m, const float pos_mm[3], float err_um[3])
{
    float X[6], Y[6], Z[6];
    lean_axis(&m->axis[0], pos_mm[0], X);
    lean_axis(&m->axis[1], pos_mm[1], Y);
    lean_axis(&m->axis[2], pos_mm[2], Z);
    const float x = pos_mm[0] - m->ref_mm[0], y = pos_mm[1] - m->ref_mm[1], z = pos_mm[2] - m->ref_mm[2];
    /* Eq. 3 (mm x urad = nm: / 1000 for um), squareness, no tool offset */
    err_um[0] = -X[0] - Y[0] + Z[0] + 1e-3f * (-y * (X[5] + Y[5]) - z * (X[4] + Y[4]) + y * m->s_xy - z * m->s_xz);
    err_um[1] = -X[1] - Y[1] + Z[1] + 1e-3f * (x * X[5] + z * (X[3] + Y[3]) - z * m->s_yz);
    err_um[2] = -X[2] - Y[2] + Z[2] + 1e-3f * (-x * X[4] + y * (X[3] + Y[3]));
}

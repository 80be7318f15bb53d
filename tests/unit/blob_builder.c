#include "blob_builder.h"

#include <string.h>

#include "abbe/model.h"

void tb_put_u32(uint8_t *p, uint32_t v)
{
    p[0] = (uint8_t)v;
    p[1] = (uint8_t)(v >> 8);
    p[2] = (uint8_t)(v >> 16);
    p[3] = (uint8_t)(v >> 24);
}

uint32_t tb_get_u32(const uint8_t *p)
{
    return (uint32_t)p[0] | ((uint32_t)p[1] << 8) | ((uint32_t)p[2] << 16) | ((uint32_t)p[3] << 24);
}

static void put_i32(uint8_t *p, int32_t v) { tb_put_u32(p, (uint32_t)v); }

static void put_f32(uint8_t *p, float f)
{
    uint32_t u;
    memcpy(&u, &f, 4);
    tb_put_u32(p, u);
}

void tb_init(tb_table_t *t)
{
    memset(t, 0, sizeof *t);
    for (int j = 0; j < 3; j++) {
        t->axis[j].travel_min_nm = 0;
        t->axis[j].travel_max_nm = 500000000;
        t->axis[j].trend_degree = 255;
    }
}

static unsigned n_basis(const tb_axis_t *a)
{
    return (a->trend_degree == 255 ? 0u : a->trend_degree + 1u) + 2u * a->harmonics[0] + 2u * a->harmonics[1];
}

static unsigned n_terms(const tb_axis_t *a)
{
    unsigned n = 0;
    for (unsigned t = 0; t < 6; t++) n += (a->term_mask >> t) & 1u;
    return n;
}

static unsigned n_coef(const tb_axis_t *a)
{
    return n_basis(a) * n_terms(a) + a->reversal_rows;
}

void tb_fix_crc(uint8_t *buf, size_t total)
{
    tb_put_u32(buf + total - 4, abbe_crc32(0, buf, total - 4));
}

size_t tb_build(const tb_table_t *t, uint8_t *buf, size_t cap)
{
    size_t total = 256;
    for (int j = 0; j < 3; j++) total += 8u * n_coef(&t->axis[j]);
    total += 4;
    if (total > cap) return 0;
    memset(buf, 0, total);
    memcpy(buf, "ABBE", 4);
    buf[TB_H_MAJOR] = 1;
    buf[TB_H_MINOR] = (uint8_t)(t->version_minor ? t->version_minor : ((t->features & 0x10u) ? 1u : 0u));
    tb_put_u32(buf + TB_H_TOTAL, (uint32_t)total);
    tb_put_u32(buf + TB_H_HEADER_SIZE, 64);
    tb_put_u32(buf + TB_H_AXIS_SIZE, 64);
    tb_put_u32(buf + TB_H_FEATURES, t->features);
    for (int k = 0; k < 3; k++) {
        put_i32(buf + TB_H_REFERENCE + 4 * k, t->reference_nm[k]);
        put_i32(buf + TB_H_TOOL + 4 * k, t->tool_nm[k]);
        put_i32(buf + TB_H_SQUARENESS + 4 * k, t->squareness_q36[k]);
    }
    size_t data = 256;
    for (int j = 0; j < 3; j++) {
        const tb_axis_t *a = &t->axis[j];
        uint8_t *r = buf + TB_AXIS(j);
        put_i32(r + TB_A_MIN, a->travel_min_nm);
        put_i32(r + TB_A_MAX, a->travel_max_nm);
        r[TB_A_MASK] = a->term_mask;
        r[TB_A_DEGREE] = a->trend_degree;
        r[TB_A_HARMONICS] = a->harmonics[0];
        r[TB_A_HARMONICS + 1] = a->harmonics[1];
        for (int b = 0; b < 2; b++) {
            put_i32(r + TB_A_PERIOD + 4 * b, a->period_nm[b]);
            put_i32(r + TB_A_ORIGIN + 4 * b, a->origin_nm[b]);
        }
        put_i32(r + TB_A_BACKLASH, a->backlash_q8);
        put_i32(r + TB_A_TAKEUP, a->takeup_nm);
        put_i32(r + TB_A_EXPANSION, a->expansion_q50);
        put_i32(r + TB_A_THERMAL_OFFSET, a->thermal_offset_q16);
        put_i32(r + TB_A_TREF, a->tref_mdegc);
        unsigned nb = n_basis(a), nt = n_terms(a), count = n_coef(a);
        tb_put_u32(r + TB_A_COEF_COUNT, count);
        r[TB_A_REVERSAL_ROWS] = a->reversal_rows;
        if (count == 0) continue;
        tb_put_u32(r + TB_A_COEF_Q, (uint32_t)data);
        tb_put_u32(r + TB_A_COEF_F32, (uint32_t)(data + 4u * count));
        unsigned col = 0;
        for (unsigned term = 0; term < 6; term++) {
            if (!((a->term_mask >> term) & 1u)) continue;
            for (unsigned row = 0; row < nb; row++) {
                unsigned i = row * nt + col;
                int32_t q = a->coef_q[i];
                put_i32(buf + data + 4u * i, q);
                put_f32(buf + data + 4u * count + 4u * i, (float)q); /* the float32 twin */
            }
            col++;
        }
        for (unsigned k = 0; k < a->reversal_rows; k++) {
            unsigned i = nb * nt + k;
            put_i32(buf + data + 4u * i, a->reversal_q[k]);
            put_f32(buf + data + 4u * count + 4u * i, (float)a->reversal_q[k]);
        }
        data += 8u * count;
    }
    tb_fix_crc(buf, total);
    return total;
}

/* Five-axis golden vectors on the target (tests/golden/golden_five.*): every
 * table and point through abbe_five_error_eval_f32 (built with
 * ABBE_FIVE_GOLDEN_F32, Cortex-M4F) or abbe_five_error_eval_q (Cortex-M4F and
 * M3; integer only, the image links no float routine). Position and
 * orientation against the float64 Python reference within
 * ABBE_GOLDEN_FIVE_TOL_PM / _PRAD; exit 0 only if all pass. */
#include "abbe/abbe.h"
#include "golden_five.h"
#include "semihost.h"

static int64_t abs64(int64_t v)
{
    return v < 0 ? -v : v;
}

#if defined(ABBE_FIVE_GOLDEN_F32)
#define VARIANT "f32"
static abbe_status_t eval(const abbe_five_model_t *m, const abbe_golden_five_point_t *p, int64_t pos_pm[3],
                          int64_t rot_prad[3])
{
    abbe_five_input_f32_t in = {{p->pos_mm[0], p->pos_mm[1], p->pos_mm[2]}, {p->angle_deg[0], p->angle_deg[1]},
                                {0.0f, 0.0f, 0.0f}, {0.0f, 0.0f, 0.0f}};
    abbe_five_error_f32_t out;
    abbe_status_t st = abbe_five_error_eval_f32(m, &in, &out);
    for (unsigned k = 0u; k < 3u; k++) {
        /* um -> pm: |error| < 2 mm, so the product is exact enough in float (0.1 pm at 1 mm... well below the tolerance) */
        float pm = out.error_um[k] * 1.0e6f, prad = out.orient_urad[k] * 1.0e6f;
        pos_pm[k] = (int64_t)pm;
        rot_prad[k] = (int64_t)prad;
    }
    return st;
}
#define EXPECT_POS(p, k) ((p)->expect_f32_pm[k])
#define EXPECT_ROT(p, k) ((p)->expect_f32_prad[k])
#else
#define VARIANT "q"
static abbe_status_t eval(const abbe_five_model_t *m, const abbe_golden_five_point_t *p, int64_t pos_pm[3],
                          int64_t rot_prad[3])
{
    abbe_five_input_q_t in = {{p->pos_nm[0], p->pos_nm[1], p->pos_nm[2]}, {p->angle_udeg[0], p->angle_udeg[1]},
                              {0, 0, 0}, {0, 0, 0}};
    abbe_five_error_q_t out;
    abbe_status_t st = abbe_five_error_eval_q(m, &in, &out);
    for (unsigned k = 0u; k < 3u; k++) {
        pos_pm[k] = (int64_t)out.error_nm[k] * 1000;
        rot_prad[k] = (int64_t)out.orient_nrad[k] * 1000;
    }
    return st;
}
#define EXPECT_POS(p, k) ((p)->expect_q_pm[k])
#define EXPECT_ROT(p, k) ((p)->expect_q_prad[k])
#endif

int main(void)
{
    uint32_t failures = 0u, n = 0u;
    int64_t worst_pos = 0, worst_rot = 0;
    sh_puts("target_golden_five_" VARIANT ": ");
    sh_put_u32(abbe_golden_five_table_count);
    sh_puts(" tables\n");
    for (uint32_t t = 0u; t < abbe_golden_five_table_count; t++) {
        const abbe_golden_five_table_t *g = &abbe_golden_five_tables[t];
        abbe_five_model_t m;
        abbe_status_t st = abbe_five_model_load(&m, g->blob, g->blob_size);
#if defined(ABBE_NO_FIVE_KINDS) /* a trunnion-only library: format 1.4's kinds refused by their minor */
        if (g->kind >= ABBE_KIN_XYZBC_HH) {
            if (st != ABBE_E_VERSION_MINOR) {
                failures++;
            }
            n += g->n_points;
            continue;
        }
#endif
        if (ABBE_FIVE_KIND_BUILT(g->kind) == 0u) { /* a library built for other kinds (ABBE_FIVE_KINDS) */
            if (st != ABBE_E_KIND) {
                failures++;
            }
            n += g->n_points;
            continue;
        }
        if (st != ABBE_OK || abbe_five_model_kind(&m) != g->kind) {
            sh_puts("FAIL load ");
            sh_puts(g->name);
            sh_puts("\n");
            failures++;
            continue;
        }
        int64_t table_pos = 0, table_rot = 0; /* this table's worst, printed per table */
        for (uint32_t i = g->first_point; i < g->first_point + g->n_points; i++) {
            const abbe_golden_five_point_t *p = &abbe_golden_five_points[i];
            int64_t pos[3], rot[3];
            if (eval(&m, p, pos, rot) != ABBE_OK) {
                failures++;
                continue;
            }
            for (unsigned k = 0u; k < 3u; k++) {
                int64_t dp = abs64(pos[k] - EXPECT_POS(p, k)), dr = abs64(rot[k] - EXPECT_ROT(p, k));
                table_pos = dp > table_pos ? dp : table_pos;
                table_rot = dr > table_rot ? dr : table_rot;
                if (dp > ABBE_GOLDEN_FIVE_TOL_PM || dr > ABBE_GOLDEN_FIVE_TOL_PRAD) {
                    if (failures < 20u) {
                        sh_puts("FAIL point #");
                        sh_put_u32(i);
                        sh_puts(" position ");
                        sh_put_i64(pos[k]);
                        sh_puts(" want ");
                        sh_put_i32(EXPECT_POS(p, k));
                        sh_puts(" orientation ");
                        sh_put_i64(rot[k]);
                        sh_puts(" want ");
                        sh_put_i32(EXPECT_ROT(p, k));
                        sh_puts("\n");
                    }
                    failures++;
                }
            }
            n++;
        }
        sh_puts(g->name);
        sh_puts(": worst position ");
        sh_put_i64(table_pos);
        sh_puts(" pm, orientation ");
        sh_put_i64(table_rot);
        sh_puts(" prad\n");
        worst_pos = table_pos > worst_pos ? table_pos : worst_pos;
        worst_rot = table_rot > worst_rot ? table_rot : worst_rot;
    }
    sh_puts("points ");
    sh_put_u32(n);
    sh_puts(", worst position ");
    sh_put_i64(worst_pos);
    sh_puts(" pm, worst orientation ");
    sh_put_i64(worst_rot);
    sh_puts(" prad, failures ");
    sh_put_u32(failures);
    sh_puts("\n");
    sh_puts(failures == 0u && n == abbe_golden_five_point_count ? "PASS\n" : "FAIL\n");
    sh_exit(failures == 0u && n == abbe_golden_five_point_count ? 0 : 1);
}

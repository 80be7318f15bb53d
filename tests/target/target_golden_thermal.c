/* Thermal golden vectors on the target (tests/golden/golden_thermal.*): the
 * format 1.3 table through abbe_thermal_load, the record through
 * abbe_thermal_update_f32 (ABBE_THERMAL_GOLDEN_F32, Cortex-M4F) or
 * abbe_thermal_update_q (M4F and M3; integer only), each sample's channel
 * values and the tool tip error against the float64 Python reference
 * (abbe.model.thermal.evaluate). Exit 0 only if all pass. */
#include "abbe/abbe.h"
#include "golden_thermal.h"
#include "semihost.h"

static int64_t abs64(int64_t v)
{
    return v < 0 ? -v : v;
}

#if defined(ABBE_THERMAL_GOLDEN_F32)
#define VARIANT "f32"
#define TOL(ref) (ABBE_GOLDEN_THERMAL_TOL_F32_ABS_NM + 1 + abs64(ref) * ABBE_GOLDEN_THERMAL_TOL_F32_REL_PPM / 1000000)
static void step(abbe_thermal_state_t *st, const abbe_golden_thermal_sample_t *s, uint32_t n, int64_t y[5], int64_t tip[3])
{
    (void)abbe_thermal_update_f32(st, s->x, 0x1FFFFu, n ? s->dt_s : 0.0f);
    float e[3] = {0.0f, 0.0f, 0.0f}, yf[5];
    abbe_thermal_apply_f32(st, e);
    (void)abbe_thermal_channels_f32(st, yf);
    for (unsigned c = 0; c < 5u; c++) {
        y[c] = (int64_t)(yf[c] * 1000.0f);
    }
    for (unsigned a = 0; a < 3u; a++) {
        tip[a] = (int64_t)(e[a] * 1000.0f);
    }
}
#define EXPECT_Y(s, c) ((s)->expect_f32[c])
#define EXPECT_TIP(s, a) ((s)->tip_f32_nm[a])
#define INIT(st, th) abbe_thermal_init_f32((st), (th), 30.0f)
#else
#define VARIANT "q"
#define TOL(ref) (ABBE_GOLDEN_THERMAL_TOL_Q_ABS_NM + 1 + abs64(ref) * ABBE_GOLDEN_THERMAL_TOL_Q_REL_PPM / 1000000)
static void step(abbe_thermal_state_t *st, const abbe_golden_thermal_sample_t *s, uint32_t n, int64_t y[5], int64_t tip[3])
{
    (void)abbe_thermal_update_q(st, s->x_milli, 0x1FFFFu, n ? s->dt_ms : 0u);
    int32_t e[3] = {0, 0, 0}, yq[5];
    abbe_thermal_apply_q(st, e);
    (void)abbe_thermal_channels_q(st, yq);
    for (unsigned c = 0; c < 5u; c++) {
        y[c] = yq[c];
    }
    for (unsigned a = 0; a < 3u; a++) {
        tip[a] = e[a];
    }
}
#define EXPECT_Y(s, c) ((s)->expect_q[c])
#define EXPECT_TIP(s, a) ((s)->tip_q_nm[a])
#define INIT(st, th) abbe_thermal_init_q((st), (th), 30000000u) /* one apply per sample = one full fade step */
#endif

int main(void)
{
    static abbe_model_t m;
    static abbe_thermal_model_t th;
    static abbe_thermal_state_t st;
    uint32_t failures = 0u;
    int64_t worst = 0;
    sh_puts("target_golden_thermal_" VARIANT ": ");
    if (abbe_thermal_load(&m, &th, abbe_golden_thermal_blob, abbe_golden_thermal_blob_size) != ABBE_OK ||
        abbe_model_load(&m, abbe_golden_thermal_blob, abbe_golden_thermal_blob_size) != ABBE_E_VERSION_MINOR ||
        INIT(&st, &th) != ABBE_OK) {
        sh_puts("FAIL load\n");
        sh_exit(1);
    }
    for (uint32_t n = 0u; n < abbe_golden_thermal_sample_count; n++) {
        const abbe_golden_thermal_sample_t *s = &abbe_golden_thermal_samples[n];
        int64_t y[5], tip[3];
        step(&st, s, n, y, tip);
        for (unsigned c = 0; c < 5u; c++) {
            int64_t d = abs64(y[c] - EXPECT_Y(s, c));
            worst = d > worst ? d : worst;
            failures += d > TOL(EXPECT_Y(s, c));
        }
        for (unsigned a = 0; a < 3u; a++) {
            failures += abs64(tip[a] - EXPECT_TIP(s, a)) > TOL(EXPECT_TIP(s, a)) + 1;
        }
        failures += (abbe_thermal_flags(&st) & ABBE_THERMAL_F_FAULTS) != 0u;
    }
    sh_put_u32(abbe_golden_thermal_sample_count);
    sh_puts(" samples, worst channel difference ");
    sh_put_u32((uint32_t)worst);
    sh_puts(" nm, failures ");
    sh_put_u32(failures);
    sh_puts(failures ? " FAIL\n" : " PASS\n");
    sh_exit(failures ? 1 : 0);
    return 0;
}

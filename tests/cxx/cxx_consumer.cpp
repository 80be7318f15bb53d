// A C++ program using abbe as C++ firmware does: every public header included
// from C++11 (-Wall -Wextra -Wpedantic -Werror), linked against the C library
// (which needs the headers' extern "C": without it every call is an
// undefined reference to a C++-mangled name), and the golden points checked.
//
// Built three ways (tests/cxx/CMakeLists.txt): against the host build, against
// an installed abbe through find_package(abbe) and through pkg-config
// (tests/install/), and as a bare-metal image for the Cortex-M4F under QEMU
// (ABBE_CXX_TARGET: output through semihosting, no C++ runtime library).
// ABBE_CXX_F32 = 0 leaves out the float variant (a library built without it).
#include "abbe/abbe.h"
#include "abbe/comp.h"
#include "abbe/error.h"
#include "abbe/model.h"
#include "abbe/status.h"
#include "abbe/version.h"

// The C headers, not <cstdint>: bare-metal toolchains often ship C++ without
// its library (Debian's arm-none-eabi-g++ has no <cstdint>).
#include <stddef.h>
#include <stdint.h>

// Test-side C headers without guards of their own.
extern "C" {
#include "golden_data.h"
#if defined(ABBE_CXX_TARGET)
#include "semihost.h"
#endif
}

#if !defined(ABBE_CXX_TARGET)
#include <cstdio>
#endif

#ifndef ABBE_CXX_F32
#define ABBE_CXX_F32 1
#endif

namespace {

void put(const char *s)
{
#if defined(ABBE_CXX_TARGET)
    sh_puts(s);
#else
    std::fputs(s, stdout);
#endif
}

void put(int64_t v)
{
#if defined(ABBE_CXX_TARGET)
    sh_put_i64(v);
#else
    std::printf("%lld", static_cast<long long>(v));
#endif
}

// The worst error of one variant over every golden point, and its failures.
struct Tally {
    const char *name;
    int64_t max_pm;
    uint32_t points;
    uint32_t failures;

    void fail(const char *what, uint32_t point, int64_t got, int64_t want)
    {
        put("FAIL ");
        put(name);
        put(" ");
        put(what);
        put(", point ");
        put(static_cast<int64_t>(point));
        put(": got ");
        put(got);
        put(", expected ");
        put(want);
        put("\n");
        ++failures;
    }

    void check(uint32_t i, abbe_status_t st, uint32_t flags, const int64_t got_pm[ABBE_AXES],
               const int32_t want_pm[ABBE_AXES], uint32_t want_flags)
    {
        ++points;
        if (st != ABBE_OK) {
            fail(abbe_strerror(st), i, st, ABBE_OK);
            return;
        }
        if (flags != want_flags) {
            fail("flags", i, flags, want_flags);
        }
        for (unsigned j = 0; j < ABBE_AXES; ++j) {
            const int64_t e = got_pm[j] > want_pm[j] ? got_pm[j] - want_pm[j] : want_pm[j] - got_pm[j];
            max_pm = e > max_pm ? e : max_pm;
            if (e > ABBE_GOLDEN_TOL_PM) {
                fail("error pm", i, got_pm[j], want_pm[j]);
            }
        }
    }

    bool report() const
    {
        put(name);
        put(": ");
        put(static_cast<int64_t>(points));
        put(" golden points, max |error| ");
        put(max_pm);
        put(" pm (tolerance ");
        put(static_cast<int64_t>(ABBE_GOLDEN_TOL_PM));
        put(" pm)\n");
        return failures == 0 && points > 0;
    }
};

#if ABBE_CXX_F32
int64_t to_pico(float um)
{
    const double v = static_cast<double>(um) * 1e6;
    return static_cast<int64_t>(v < 0.0 ? v - 0.5 : v + 0.5);
}

void check_f32(const abbe_model_t &m, uint32_t i, const abbe_golden_point_t &p, Tally &t)
{
    abbe_input_f32_t in;
    abbe_error_f32_t out = {};
    for (unsigned j = 0; j < ABBE_AXES; ++j) {
        in.pos_mm[j] = p.pos_mm[j];
        in.dir_state[j] = p.dir_state[j];
        in.temp_c[j] = p.temp_c[j];
    }
    const abbe_status_t st = abbe_error_eval_f32(&m, &in, &out);
    int64_t got[ABBE_AXES];
    for (unsigned j = 0; j < ABBE_AXES; ++j) {
        got[j] = to_pico(out.error_um[j]);
    }
    t.check(i, st, out.flags, got, p.expect_f32_pm, p.expect_flags);
}
#endif

void check_q(const abbe_model_t &m, uint32_t i, const abbe_golden_point_t &p, Tally &t)
{
    abbe_input_q_t in;
    abbe_error_q_t out = {};
    for (unsigned j = 0; j < ABBE_AXES; ++j) {
        in.pos_nm[j] = p.pos_nm[j];
        in.dir_state_q30[j] = p.dir_q30[j];
        in.temp_mdegc[j] = p.temp_mdegc[j];
    }
    const abbe_status_t st = abbe_error_eval_q(&m, &in, &out);
    int64_t got[ABBE_AXES];
    for (unsigned j = 0; j < ABBE_AXES; ++j) {
        got[j] = static_cast<int64_t>(out.error_nm[j]) * 1000;
    }
    t.check(i, st, out.flags, got, p.expect_q_pm, p.expect_flags);
}

} // namespace

int main()
{
    put("abbe " ABBE_VERSION_STRING " from C++: ");
    put(static_cast<int64_t>(abbe_golden_table_count));
    put(" golden tables\n");
    // A value every build knows, through the core (crc32 and the loader).
    // 4-byte aligned: the loader checks alignment (ABBE_E_ALIGN) before length, and a
    // char array may land at any address (clang's M3 image put it at an odd one).
    alignas(4) static const char check[] = "123456789";
    abbe_model_t model;
    if (abbe_crc32(0u, check, sizeof check - 1u) != 0xCBF43926u ||
        abbe_model_load(&model, check, sizeof check - 1u) != ABBE_E_TRUNCATED) {
        put("FAIL crc32 or load of a truncated blob\n");
        return 1;
    }

    Tally q = {"q", 0, 0, 0};
#if ABBE_CXX_F32
    Tally f32 = {"f32", 0, 0, 0};
#endif
    uint32_t load_failures = 0;
    for (uint32_t t = 0; t < abbe_golden_table_count; ++t) {
        const abbe_golden_table_t &gt = abbe_golden_tables[t];
        const abbe_status_t st = abbe_model_load(&model, gt.blob, gt.blob_size);
        if (st != ABBE_OK) {
            put("FAIL load ");
            put(gt.name);
            put(": ");
            put(abbe_strerror(st));
            put("\n");
            ++load_failures;
            continue;
        }
        for (uint32_t i = gt.first_point; i < gt.first_point + gt.n_points; ++i) {
            check_q(model, i, abbe_golden_points[i], q);
#if ABBE_CXX_F32
            check_f32(model, i, abbe_golden_points[i], f32);
#endif
        }
    }
    bool ok = q.report() && load_failures == 0;
#if ABBE_CXX_F32
    ok = f32.report() && ok;
#endif
    put(ok ? "cxx_consumer: PASS\n" : "cxx_consumer: FAIL\n");
    return ok ? 0 : 1;
}

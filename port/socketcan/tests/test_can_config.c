/* The configuration file: values and defaults, and every kind of error names
 * the file, the line and the field. */
#define _POSIX_C_SOURCE 200809L

#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>
#include <string.h>

#include <cmocka.h>

#include "abbe_can.h"
#include "abbe_can_config.h"
#include "can_test_util.h"

/* Line numbers matter below: keep this text and the cases in step. */
static const char GOOD[] =
    "# test configuration\n"                       /* 1 */
    "[bus]\n"                                      /* 2 */
    "interface = \"vcan0\"   # comment\n"          /* 3 */
    "sync_cob_id = 0x080\n"                        /* 4 */
    "\n"                                           /* 5 */
    "[model]\n"                                    /* 6 */
    "path = \"tables/model.bin\"\n"                /* 7 */
    "\n"                                           /* 8 */
    "[status]\n"                                   /* 9 */
    "info_period_cycles = 1_000\n"                 /* 10 */
    "\n"                                           /* 11 */
    "[compensator]\n"                              /* 12 */
    "fade_cycles = 50\n"                           /* 13 */
    "enable_on_start = false\n"                    /* 14 */
    "\n"                                           /* 15 */
    "[axis.X]\n"                                   /* 16 */
    "node_id = 1\n"                                /* 17 */
    "increments_per_mm = 10000\n"                  /* 18 */
    "warn_um = 40.5\n"                             /* 19 */
    "\n"                                           /* 20 */
    "[axis.Y]\n"                                   /* 21 */
    "node_id = 2\n"                                /* 22 */
    "increments_per_mm = 2.6214e4\n"               /* 23 */
    "sign = -1\n"                                  /* 24 */
    "origin_mm = -400.25\n"                        /* 25 */
    "\n"                                           /* 26 */
    "[axis.Z]\n"                                   /* 27 */
    "node_id = 0x10\n"                             /* 28 */
    "increments_per_mm = 1000\n"                   /* 29 */
    "tpdo_dlc = 8\n"                               /* 30 */
    "statusword_byte = 0\n"                        /* 31 */
    "position_byte = 2\n"                          /* 32 */
    "\n"                                           /* 33 */
    "[temperature]\n"                              /* 34 */
    "enable = true\n"                              /* 35 */
    "stale_cycles = 200\n";                        /* 36 */

static void test_good_file(void **state)
{
    (void)state;
    abbe_can_config_t c;
    abbe_can_config_error_t e;
    int st = abbe_can_config_parse(&c, GOOD, strlen(GOOD), "/etc/abbe/can.toml", &e);
    if (st != ABBE_CAN_OK) {
        char msg[1024];
        abbe_can_config_error_format(&e, msg, sizeof msg);
        fail_msg("%s", msg);
    }
    assert_string_equal(c.interface, "vcan0");
    assert_string_equal(c.model_path, "/etc/abbe/tables/model.bin"); /* relative to the file */
    assert_int_equal(c.sync_cob_id, 0x080);
    assert_int_equal(c.info_period_cycles, 1000);
    assert_int_equal(c.fade_cycles, 50);
    assert_int_equal(c.stale_cycles, 10);  /* default */
    assert_int_equal(c.enable_on_start, 0);
    assert_int_equal(c.status_cob_id, 0x1F0); /* derived from the default node id 0x70 */
    assert_int_equal(c.info_cob_id, 0x2F0);
    assert_int_equal(c.command_cob_id, 0x270);
    assert_int_equal(c.axis[0].warn_nm, 40500);
    assert_int_equal(c.axis[0].limit_nm, 100000);
    assert_int_equal(c.axis[0].tpdo_cob_id, 0x181);
    assert_int_equal(c.axis[0].rpdo_cob_id, 0x201);
    assert_true(c.axis[1].increments_per_mm > 26213.9 && c.axis[1].increments_per_mm < 26214.1);
    assert_int_equal(c.axis[1].sign, -1);
    assert_int_equal(c.axis[1].origin_nm, -400250000);
    assert_int_equal(c.axis[2].node_id, 16);
    assert_int_equal(c.axis[2].tpdo_cob_id, 0x190);
    assert_int_equal(c.axis[2].statusword_byte, 0);
    assert_int_equal(c.axis[2].position_byte, 2);
    assert_int_equal(c.axis[2].statusword_byte, 0);
    assert_int_equal(c.axis[0].statusword_byte, ABBE_CAN_NO_BYTE);
    assert_int_equal(c.temp_enable, 1);
    assert_int_equal(c.temp_cob_id, 0x370); /* 0x300 + the default node id: the compensator's RPDO2 */
    assert_int_equal(c.temp_stale_cycles, 200);
    for (unsigned j = 0; j < 3; j++) {
        assert_int_equal(c.axis[j].temp_mdegc, 20000);
    }

    /* CRLF line ends and a name without a directory */
    char crlf[2 * sizeof GOOD];
    size_t n = 0;
    for (const char *p = GOOD; *p; p++) {
        if (*p == '\n') {
            crlf[n++] = '\r';
        }
        crlf[n++] = *p;
    }
    assert_int_equal(abbe_can_config_parse(&c, crlf, n, "can.toml", &e), ABBE_CAN_OK);
    assert_string_equal(c.model_path, "tables/model.bin");
}

/* Replace line `line` (1-based) of GOOD with `text` ("" deletes it; text may hold several lines). */
static size_t edit(char *out, size_t cap, unsigned line, const char *text)
{
    size_t n = 0;
    unsigned l = 1;
    const char *p = GOOD;
    while (*p) {
        const char *end = strchr(p, '\n');
        size_t len = (size_t)(end - p) + 1u;
        if (l == line) {
            size_t t = strlen(text);
            assert_true(n + t + 1 < cap);
            memcpy(out + n, text, t);
            n += t;
            if (t > 0 && text[t - 1] != '\n') {
                out[n++] = '\n';
            }
        } else {
            assert_true(n + len < cap);
            memcpy(out + n, p, len);
            n += len;
        }
        p = end + 1;
        l++;
    }
    out[n] = '\0';
    return n;
}

typedef struct {
    unsigned line;          /* line to replace */
    const char *text;       /* its replacement */
    unsigned want_line;     /* expected error line */
    const char *want_field; /* expected field */
    const char *want_msg;   /* expected part of the message */
} bad_case_t;

static const bad_case_t BAD[] = {
    {17, "nod_id = 1", 17, "axis.X.nod_id", "unknown key"},
    {16, "[axis.W]", 16, "axis.W", "unknown section"},
    {16, "[axis.X", 16, "axis.X", "malformed section header"},
    {21, "[axis.X]", 21, "axis.X", "section appears twice"},
    {19, "warn_um = 40.5\nwarn_um = 41", 20, "axis.X.warn_um", "set twice"},
    {24, "sign = \"-1\"", 24, "axis.Y.sign", "expected a number, not a string"},
    {24, "sign = 2", 24, "axis.Y.sign", "must be -1..1"},
    {24, "sign = 0", 24, "axis.Y.sign", "must be 1 or -1"},
    {17, "node_id = 200", 17, "axis.X.node_id", "must be 1..127"},
    {17, "node_id = 1.5", 17, "axis.X.node_id", "expected an integer"},
    {4, "sync_cob_id = 0x800", 4, "bus.sync_cob_id", "must be 0x001..0x7FF"},
    {14, "enable_on_start = yes", 14, "compensator.enable_on_start", "expected true or false"},
    {3, "interface = \"vcan0", 3, "bus.interface", "unterminated string"},
    {3, "interface = \"averyverylongifname\"", 3, "bus.interface", "string too long"},
    {3, "interface = vcan0", 3, "bus.interface", "expected a \"string\""},
    {7, "path = \"a\\tb\"", 7, "model.path", "unsupported escape"},
    {7, "path = \"\"", 7, "model.path", "must not be empty"},
    {13, "fade_cycles = 50 60", 13, "compensator.fade_cycles", "unexpected text after the value"},
    {13, "fade_cycles =", 13, "compensator.fade_cycles", "missing value"},
    {13, "fade_cycles 50", 13, "compensator.fade_cycles", "expected '='"},
    {13, "fade_cycles = 0", 13, "compensator.fade_cycles", "must be 1..65535"},
    {23, "increments_per_mm = nan", 23, "axis.Y.increments_per_mm", "expected a number"},
    {23, "increments_per_mm = -5", 23, "axis.Y.increments_per_mm", "must be > 0"},
    {18, "", 16, "axis.X.increments_per_mm", "missing (required)"},
    {7, "", 6, "model.path", "missing (required)"},
    {1, "foo = 1", 1, "foo", "key outside a section"},
    {1, "= 1", 1, "", "expected key = value"},
    {19, "warn_um = 150", 16, "axis.X.limit_um", "must be >= warn_um"},
    {19, "warn_um = 1e12", 19, "axis.X.warn_um", "value out of range"},
    {19, "position_byte = 1", 19, "axis.X.position_byte", "must fit in tpdo_dlc"},
    {32, "position_byte = 5", 32, "axis.Z.position_byte", "must be 0..4"},
    {32, "position_byte = 1", 31, "axis.Z.statusword_byte", "overlaps the position bytes"},
    {25, "rpdo_cob_id = 0x080", 25, "axis.Y.rpdo_cob_id", "already used by bus.sync_cob_id"},
    {25, "rpdo_cob_id = 0x181", 25, "axis.Y.rpdo_cob_id", "already used by an axis' tpdo_cob_id"},
    {10, "cob_id = 0x181", 16, "axis.X.tpdo_cob_id", "already used by status.cob_id"},
    {25, "tpdo_cob_id = 0x190", 30, "axis.Z.tpdo_dlc", "axes sharing a TPDO"}, /* Y joins Z's TPDO */
    {35, "enable = true\ncob_id = 0x080", 36, "temperature.cob_id", "already used by bus.sync_cob_id"},
    {35, "enable = true\ncob_id = 0x202", 21, "axis.Y.rpdo_cob_id", "already used by temperature.cob_id"},
    {36, "stale_cycles = -1", 36, "temperature.stale_cycles", "must be 0..65535"},
    {35, "enable = 1", 35, "temperature.enable", "expected true or false"},
    {35, "enabled = true", 35, "temperature.enabled", "unknown key"},
    {19, "temp_c = 150.01", 19, "axis.X.temp_c", "must be -50..150 (degC)"},
    {19, "temp_c = -51", 19, "axis.X.temp_c", "must be -50..150 (degC)"},
    /* numbers follow TOML (what tomllib refuses is refused here too) */
    {17, "node_id = 01", 17, "axis.X.node_id", "expected an integer"},
    {17, "node_id = 0X1", 17, "axis.X.node_id", "expected an integer"},
    {17, "node_id = 1__0", 17, "axis.X.node_id", "expected an integer"},
    {17, "node_id = _1", 17, "axis.X.node_id", "expected an integer"},
    {17, "node_id = 1_", 17, "axis.X.node_id", "expected an integer"},
    {17, "node_id = 0x_1", 17, "axis.X.node_id", "expected an integer"},
    {17, "node_id = -0x1", 17, "axis.X.node_id", "expected an integer"},
    {17, "node_id = 99999999999999999999", 17, "axis.X.node_id", "must be 1..127"},
    {19, "warn_um = .5", 19, "axis.X.warn_um", "expected a number"},
    {19, "warn_um = 5.", 19, "axis.X.warn_um", "expected a number"},
    {19, "warn_um = 5.e1", 19, "axis.X.warn_um", "expected a number"},
    {19, "warn_um = 1e", 19, "axis.X.warn_um", "expected a number"},
    {19, "warn_um = 0x1p3", 19, "axis.X.warn_um", "expected a number"},
    {19, "warn_um = -0x10", 19, "axis.X.warn_um", "expected a number"},
    {19, "warn_um = 00.5", 19, "axis.X.warn_um", "expected a number"},
    {19, "warn_um = inf", 19, "axis.X.warn_um", "expected a number"},
    {19, "warn_um = 1e400", 19, "axis.X.warn_um", "value out of range"},
    {19, "warn_um = 1e299", 19, "axis.X.warn_um", "value out of range"},
};

static void check_case(const bad_case_t *bc, const char *text, size_t n, const char *name)
{
    abbe_can_config_t c;
    abbe_can_config_error_t e;
    int st = abbe_can_config_parse(&c, text, n, name, &e);
    char msg[1024];
    abbe_can_config_error_format(&e, msg, sizeof msg);
    if (st != ABBE_CAN_E_CONFIG) {
        fail_msg("line %u '%s': accepted", bc->line, bc->text);
    }
    if (e.line != bc->want_line || strcmp(e.field, bc->want_field) != 0 || strstr(e.message, bc->want_msg) == NULL) {
        fail_msg("line %u '%s': got '%s'", bc->line, bc->text, msg);
    }
    assert_string_equal(e.file, name);
    char want[512];
    if (bc->want_field[0] != '\0') {
        snprintf(want, sizeof want, "%s:%u: field '%s': ", name, bc->want_line, bc->want_field);
    } else {
        snprintf(want, sizeof want, "%s:%u: ", name, bc->want_line);
    }
    assert_int_equal(strncmp(msg, want, strlen(want)), 0);
}

static void test_errors(void **state)
{
    (void)state;
    for (size_t i = 0; i < sizeof BAD / sizeof BAD[0]; i++) {
        char text[4096];
        size_t n = edit(text, sizeof text, BAD[i].line, BAD[i].text);
        check_case(&BAD[i], text, n, "cfg/can.toml");
    }
}

/* Spellings TOML allows, with their values. */
static void test_number_syntax(void **state)
{
    (void)state;
    static const struct {
        const char *text;
        int32_t warn_nm;
    } ok[] = {
        {"warn_um = +4_0.5e0", 40500}, {"warn_um = 4.05E+1", 40500}, {"warn_um = 40", 40000},
        {"warn_um = 0.0405e3", 40500}, {"warn_um = 1_0", 10000},     {"warn_um = 0x28", 40000},
    };
    for (size_t i = 0; i < sizeof ok / sizeof ok[0]; i++) {
        char text[4096];
        size_t n = edit(text, sizeof text, 19, ok[i].text);
        abbe_can_config_t c;
        abbe_can_config_error_t e;
        if (abbe_can_config_parse(&c, text, n, "can.toml", &e) != ABBE_CAN_OK) {
            fail_msg("'%s' refused: %s", ok[i].text, e.message);
        }
        assert_int_equal(c.axis[0].warn_nm, ok[i].warn_nm);
    }
}

static void test_missing_section(void **state)
{
    (void)state;
    char text[4096];
    size_t n = 0;
    /* everything before [axis.Z] */
    const char *z = strstr(GOOD, "[axis.Z]");
    n = (size_t)(z - GOOD);
    memcpy(text, GOOD, n);
    abbe_can_config_t c;
    abbe_can_config_error_t e;
    assert_int_equal(abbe_can_config_parse(&c, text, n, "can.toml", &e), ABBE_CAN_E_CONFIG);
    assert_string_equal(e.field, "axis.Z");
    assert_int_equal(e.line, 26); /* the end of the file */
    assert_non_null(strstr(e.message, "missing section [axis.Z]"));
}

static void test_files(void **state)
{
    (void)state;
    char dir[256], path[512];
    ctu_tmpdir(dir, sizeof dir);
    abbe_can_config_t c;
    abbe_can_config_error_t e;
    char msg[1024];

    snprintf(path, sizeof path, "%s/can.toml", dir);
    ctu_write_file(path, GOOD, strlen(GOOD));
    assert_int_equal(abbe_can_config_load(&c, path, &e), ABBE_CAN_OK);
    char want[600];
    snprintf(want, sizeof want, "%s/tables/model.bin", dir);
    assert_string_equal(c.model_path, want);

    char text[4096];
    size_t n = edit(text, sizeof text, 28, "node_id = 0");
    ctu_write_file(path, text, n);
    assert_int_equal(abbe_can_config_load(&c, path, &e), ABBE_CAN_E_CONFIG);
    assert_int_equal(e.line, 28);
    assert_string_equal(e.field, "axis.Z.node_id");
    assert_string_equal(e.file, path);

    /* unreadable: no line, no field */
    snprintf(path, sizeof path, "%s/missing.toml", dir);
    assert_int_equal(abbe_can_config_load(&c, path, &e), ABBE_CAN_E_CONFIG);
    assert_int_equal(e.line, 0);
    abbe_can_config_error_format(&e, msg, sizeof msg);
    snprintf(want, sizeof want, "%s: cannot open: No such file or directory", path);
    assert_string_equal(msg, want);

    /* a line longer than the limit */
    static char longline[ABBE_CAN_LINE_MAX + 64];
    memset(longline, '#', sizeof longline - 2);
    longline[sizeof longline - 2] = '\n';
    longline[sizeof longline - 1] = '\0';
    snprintf(path, sizeof path, "%s/long.toml", dir);
    ctu_write_file(path, longline, strlen(longline));
    assert_int_equal(abbe_can_config_load(&c, path, &e), ABBE_CAN_E_CONFIG);
    assert_int_equal(e.line, 1);
    assert_non_null(strstr(e.message, "line too long"));

    /* a NUL byte */
    snprintf(path, sizeof path, "%s/nul.toml", dir);
    ctu_write_file(path, "[bus]\nnode_id = 1\0\n", 20);
    assert_int_equal(abbe_can_config_load(&c, path, &e), ABBE_CAN_E_CONFIG);
    assert_int_equal(e.line, 2);
    assert_non_null(strstr(e.message, "NUL"));
    ctu_rmtree(dir);
}

static void test_check_direct(void **state)
{
    (void)state;
    abbe_can_config_t c;
    abbe_can_config_defaults(&c);
    const char *field = NULL, *why = NULL;
    assert_int_equal(abbe_can_config_check(&c, &field, &why), ABBE_CAN_E_CONFIG);
    assert_string_equal(field, "axis.X.node_id");
    for (unsigned j = 0; j < 3; j++) {
        c.axis[j].node_id = (uint8_t)(j + 1u);
        c.axis[j].increments_per_mm = 1000.0;
    }
    assert_int_equal(abbe_can_config_check(&c, &field, &why), ABBE_CAN_OK);
    /* two axes in one RPDO: fine side by side, refused when they overlap */
    c.axis[0].rpdo_cob_id = c.axis[1].rpdo_cob_id = 0x301;
    c.axis[0].rpdo_dlc = c.axis[1].rpdo_dlc = 8;
    c.axis[1].offset_byte = 4;
    assert_int_equal(abbe_can_config_check(&c, &field, &why), ABBE_CAN_OK);
    c.axis[1].offset_byte = 2;
    assert_int_equal(abbe_can_config_check(&c, &field, &why), ABBE_CAN_E_CONFIG);
    assert_string_equal(field, "axis.Y.offset_byte");
    c.axis[1].offset_byte = 4;
    c.axis[1].rpdo_dlc = 7;
    c.axis[1].offset_byte = 3;
    assert_int_equal(abbe_can_config_check(&c, &field, &why), ABBE_CAN_E_CONFIG);
    assert_string_equal(field, "axis.Y.rpdo_dlc");
    c.axis[1].rpdo_dlc = 8;
    c.axis[1].offset_byte = 4;
    c.status_enable = 0;
    c.command_enable = 0;
    c.info_period_cycles = 0;
    c.axis[2].rpdo_cob_id = c.status_cob_id; /* status is off: its id is free */
    assert_int_equal(abbe_can_config_check(&c, &field, &why), ABBE_CAN_OK);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_number_syntax),
        cmocka_unit_test(test_good_file),       cmocka_unit_test(test_errors),
        cmocka_unit_test(test_missing_section), cmocka_unit_test(test_files),
        cmocka_unit_test(test_check_direct),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}

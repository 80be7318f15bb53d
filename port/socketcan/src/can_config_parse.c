/* abbe CAN port: configuration text parser (host; a TOML subset, no heap).
 * The numbers' syntax is can_toml_number.c; reading the file, can_config_file.c. */
#include <limits.h>
#include <stddef.h>
#include <stdio.h>
#include <string.h>

#include "abbe_can_config.h"
#include "can_internal.h"
#include "can_toml_number.h"

typedef enum {
    V_U8,       /* integer into uint8_t */
    V_U16,      /* integer into uint16_t */
    V_U32,      /* integer into uint32_t (COB-IDs) */
    V_I8,       /* integer into int8_t */
    V_BOOL,     /* true/false into uint8_t */
    V_STR,      /* "string" into char[cap] */
    V_DOUBLE,   /* number into double */
    V_SCALED    /* number times scale, rounded, into int32_t */
} vkind_t;

/* The configuration's fields, one id each: a value is stored by a switch over
 * the id into the named member (not through an offset), so the store's target
 * and its type are evident (tests/proofs/can_config.c). */
typedef enum {
    F_BUS_INTERFACE, F_BUS_NODE_ID, F_BUS_SYNC_COB_ID, F_MODEL_PATH,
    F_STATUS_ENABLE, F_STATUS_COB_ID, F_STATUS_INFO_COB_ID, F_STATUS_INFO_PERIOD,
    F_COMMAND_ENABLE, F_COMMAND_COB_ID,
    F_COMP_FADE_CYCLES, F_COMP_STALE_CYCLES, F_COMP_ENABLE_ON_START,
    F_TEMP_ENABLE, F_TEMP_COB_ID, F_TEMP_STALE_CYCLES,
    F_THERMAL_ENABLE, F_THERMAL_COB_ID, F_THERMAL_CYCLE_US,
    F_AX_NODE_ID, F_AX_INCREMENTS_PER_MM, F_AX_SIGN, F_AX_ORIGIN, F_AX_CORRECTION_SIGN,
    F_AX_WARN, F_AX_LIMIT, F_AX_RATE, F_AX_DEADBAND, F_AX_TEMP,
    F_AX_TPDO_COB_ID, F_AX_TPDO_DLC, F_AX_POSITION_BYTE, F_AX_STATUSWORD_BYTE,
    F_AX_RPDO_COB_ID, F_AX_RPDO_DLC, F_AX_OFFSET_BYTE
} field_id_t;

typedef struct {
    const char *section; /* "axis" matches axis.X/Y/Z; the member is then the axis config's */
    const char *key;
    vkind_t kind;
    field_id_t id;
    long long min, max;  /* integers: accepted range */
    double scale;        /* V_SCALED: file unit -> stored unit */
    int required;
} field_t;

static const field_t FIELDS[] = {
    {"bus", "interface", V_STR, F_BUS_INTERFACE, 0, 0, 0, 0},
    {"bus", "node_id", V_U8, F_BUS_NODE_ID, 1, 127, 0, 0},
    {"bus", "sync_cob_id", V_U32, F_BUS_SYNC_COB_ID, 1, 0x7FF, 0, 0},
    {"model", "path", V_STR, F_MODEL_PATH, 0, 0, 0, 1},
    {"status", "enable", V_BOOL, F_STATUS_ENABLE, 0, 1, 0, 0},
    {"status", "cob_id", V_U32, F_STATUS_COB_ID, 1, 0x7FF, 0, 0},
    {"status", "info_cob_id", V_U32, F_STATUS_INFO_COB_ID, 1, 0x7FF, 0, 0},
    {"status", "info_period_cycles", V_U16, F_STATUS_INFO_PERIOD, 0, 65535, 0, 0},
    {"command", "enable", V_BOOL, F_COMMAND_ENABLE, 0, 1, 0, 0},
    {"command", "cob_id", V_U32, F_COMMAND_COB_ID, 1, 0x7FF, 0, 0},
    {"compensator", "fade_cycles", V_U16, F_COMP_FADE_CYCLES, 1, 65535, 0, 0},
    {"compensator", "stale_cycles", V_U16, F_COMP_STALE_CYCLES, 1, 65535, 0, 0},
    {"compensator", "enable_on_start", V_BOOL, F_COMP_ENABLE_ON_START, 0, 1, 0, 0},
    {"temperature", "enable", V_BOOL, F_TEMP_ENABLE, 0, 1, 0, 0},
    {"temperature", "cob_id", V_U32, F_TEMP_COB_ID, 1, 0x7FF, 0, 0},
    {"temperature", "stale_cycles", V_U16, F_TEMP_STALE_CYCLES, 0, 65535, 0, 0},
    {"thermal", "enable", V_BOOL, F_THERMAL_ENABLE, 0, 1, 0, 0},
    {"thermal", "cob_id", V_U32, F_THERMAL_COB_ID, 1, 0x7FB, 0, 0},
    {"thermal", "cycle_us", V_U32, F_THERMAL_CYCLE_US, 100, 1000000, 0, 0},
    {"axis", "node_id", V_U8, F_AX_NODE_ID, 1, 127, 0, 1},
    {"axis", "increments_per_mm", V_DOUBLE, F_AX_INCREMENTS_PER_MM, 0, 0, 0, 1},
    {"axis", "sign", V_I8, F_AX_SIGN, -1, 1, 0, 0},
    {"axis", "origin_mm", V_SCALED, F_AX_ORIGIN, 0, 0, 1e6, 0},
    {"axis", "correction_sign", V_I8, F_AX_CORRECTION_SIGN, -1, 1, 0, 0},
    {"axis", "warn_um", V_SCALED, F_AX_WARN, 0, 0, 1e3, 0},
    {"axis", "limit_um", V_SCALED, F_AX_LIMIT, 0, 0, 1e3, 0},
    {"axis", "rate_um_per_cycle", V_SCALED, F_AX_RATE, 0, 0, 1e3, 0},
    {"axis", "deadband_um", V_SCALED, F_AX_DEADBAND, 0, 0, 1e3, 0},
    {"axis", "temp_c", V_SCALED, F_AX_TEMP, 0, 0, 1e3, 0},
    {"axis", "tpdo_cob_id", V_U32, F_AX_TPDO_COB_ID, 1, 0x7FF, 0, 0},
    {"axis", "tpdo_dlc", V_U8, F_AX_TPDO_DLC, 4, 8, 0, 0},
    {"axis", "position_byte", V_U8, F_AX_POSITION_BYTE, 0, 4, 0, 0},
    {"axis", "statusword_byte", V_I8, F_AX_STATUSWORD_BYTE, -1, 6, 0, 0},
    {"axis", "rpdo_cob_id", V_U32, F_AX_RPDO_COB_ID, 1, 0x7FF, 0, 0},
    {"axis", "rpdo_dlc", V_U8, F_AX_RPDO_DLC, 4, 8, 0, 0},
    {"axis", "offset_byte", V_U8, F_AX_OFFSET_BYTE, 0, 4, 0, 0},
};
#define N_FIELDS (sizeof FIELDS / sizeof FIELDS[0])

/* Fixed-width names (each a string in 12 bytes): a scan of any of them stays
 * inside its 12 bytes, which the proof sees without knowing which one. */
#define SECTION_NAME_MAX 12u
static const char SECTIONS[][SECTION_NAME_MAX] = {"bus", "model", "status", "command", "compensator", "temperature",
                                       "thermal", "axis.X", "axis.Y", "axis.Z"};
#define N_SECTIONS (sizeof SECTIONS / sizeof SECTIONS[0])
#define AXIS_SECTION0 7u /* index of axis.X */
typedef char abbe_can_axis_sections_last[(N_SECTIONS == AXIS_SECTION0 + ABBE_AXES) ? 1 : -1];

#define MAX_SEEN 160u

typedef struct {
    abbe_can_config_t *cfg;
    abbe_can_config_error_t *err;
    const char *name;
    int section;                          /* index into SECTIONS, -1 before the first */
    unsigned section_line[N_SECTIONS];    /* 0: section absent */
    char seen_field[MAX_SEEN][48];
    unsigned seen_line[MAX_SEEN];
    unsigned n_seen;
    unsigned last_line;
    /* the last byte of the line buffer, always '\0' (the line ends before it):
     * every scan of the line also stops there, which never binds but makes
     * each read's bound evident to the proof (tests/proofs/can_config.c) */
    const char *end;
} parser_t;

static void copy_str(char *dst, size_t cap, const char *src)
{
    size_t n = strlen(src);
    if (n >= cap) {
        n = cap - 1u;
    }
    memcpy(dst, src, n);
    dst[n] = '\0';
}

/* copy_str for a src that may be any of several literals (the check's field
 * and reason): strncpy reads src up to its terminator only, so each literal
 * is read only within itself, which the proof sees without knowing which
 * one (tests/proofs/can_config.c); strlen's longest would not be. */
static void copy_literal(char *dst, size_t cap, const char *src)
{
    (void)strncpy(dst, src, cap - 1u);
    dst[cap - 1u] = '\0';
}

static int error(parser_t *ps, unsigned line, const char *field, const char *message)
{
    abbe_can_config_error_t *e = ps->err;
    if (e != NULL) {
        copy_str(e->file, sizeof e->file, ps->name);
        e->line = line;
        copy_str(e->field, sizeof e->field, field != NULL ? field : "");
        copy_str(e->message, sizeof e->message, message);
    }
    return ABBE_CAN_E_CONFIG;
}

/* error() for the check's verdict (abbe_can_config_check: field and reason
 * literals). */
static int error_of_check(parser_t *ps, unsigned line, const char *field, const char *why)
{
    abbe_can_config_error_t *e = ps->err;
    if (e != NULL) {
        copy_str(e->file, sizeof e->file, ps->name);
        e->line = line;
        copy_literal(e->field, sizeof e->field, field);
        copy_literal(e->message, sizeof e->message, why);
    }
    return ABBE_CAN_E_CONFIG;
}

static int is_space(char c)
{
    return c == ' ' || c == '\t';
}

static const char *skip_space(const parser_t *ps, const char *p)
{
    while (p < ps->end && is_space(*p)) {
        p++;
    }
    return p;
}

/* After a value or header: only blanks and an optional comment may follow. */
static int rest_is_empty(const parser_t *ps, const char *p)
{
    p = skip_space(ps, p);
    return p >= ps->end || *p == '\0' || *p == '#';
}

static int is_key_char(char c)
{
    return (c >= 'a' && c <= 'z') || (c >= 'A' && c <= 'Z') || (c >= '0' && c <= '9') || c == '_' ||
           c == '-';
}

static int parse_header(parser_t *ps, const char *p, unsigned line)
{
    char name[48] = {0};
    size_t n = 0;
    p = skip_space(ps, p + 1);
    while (p < ps->end && *p != ']' && *p != '\0') {
        if (!is_space(*p)) {
            if (n + 1u >= sizeof name) {
                return error(ps, line, NULL, "section name too long");
            }
            name[n++] = *p;
        }
        p++;
    }
    name[n] = '\0';
    if (p >= ps->end || *p != ']' || !rest_is_empty(ps, p + 1)) {
        return error(ps, line, name, "malformed section header: expected [name]");
    }
    for (unsigned s = 0; s < N_SECTIONS; s++) {
        if (strcmp(name, SECTIONS[s]) == 0) {
            if (ps->section_line[s] != 0u) {
                return error(ps, line, name, "section appears twice");
            }
            ps->section = (int)s;
            ps->section_line[s] = line;
            return ABBE_CAN_OK;
        }
    }
    if (strcmp(name, "axis") == 0) { /* TOML allows [axis] before [axis.X]; nothing to set there */
        ps->section = -2;
        return ABBE_CAN_OK;
    }
    return error(ps, line, name,
                 "unknown section (expected bus, model, status, command, compensator, temperature, thermal, axis.X, "
                 "axis.Y, axis.Z)");
}

/* A value token: a "string", or the characters of a number / true / false. */
typedef struct {
    char text[ABBE_CAN_PATH_MAX];
    int is_string;
} token_t;

static const char *read_value(parser_t *ps, const char *p, unsigned line, const char *field, token_t *tok,
                              int *status)
{
    size_t n = 0;
    *status = ABBE_CAN_OK;
    tok->is_string = 0;
    if (*p == '"') {
        tok->is_string = 1;
        p++;
        while (p < ps->end && *p != '"') {
            char c = *p;
            if (c == '\0') {
                *status = error(ps, line, field, "unterminated string: expected a closing \"");
                return p;
            }
            if (c == '\\') {
                p++;
                if (*p != '\\' && *p != '"') {
                    *status = error(ps, line, field, "unsupported escape (only \\\\ and \\\" are allowed)");
                    return p;
                }
                c = *p;
            }
            if (n + 1u >= sizeof tok->text) {
                *status = error(ps, line, field, "string too long");
                return p;
            }
            tok->text[n++] = c;
            p++;
        }
        if (p >= ps->end) { /* never: the line's '\0' comes first and is refused above */
            *status = error(ps, line, field, "unterminated string: expected a closing \"");
            return p;
        }
        tok->text[n] = '\0';
        return p + 1;
    }
    while (p < ps->end && *p != '\0' && !is_space(*p) && *p != '#') {
        if (n + 1u >= 64u) {
            *status = error(ps, line, field, "value too long");
            return p;
        }
        tok->text[n++] = *p;
        p++;
    }
    tok->text[n] = '\0';
    if (n == 0) {
        *status = error(ps, line, field, "missing value");
    }
    return p;
}

/* A string into its member; 0 if the id is not a string field's or the text
 * (n characters) does not fit (store has checked both: never). */
static int put_str(abbe_can_config_t *cfg, field_id_t id, const char *text, size_t n)
{
    /* the copy stays inside its member: Eva's memory checks see the whole
     * configuration, so a copy past the member into the next one would not be
     * an alarm by itself; the assertions (proven) make it one */
    size_t len = n + 1u; /* the text and its terminator */
    switch (id) {
    case F_BUS_INTERFACE:
        if (len > sizeof cfg->interface) {
            return 0;
        }
        /*@ assert interface_inside: len <= ABBE_CAN_IFNAME_MAX; */
        memcpy(cfg->interface, text, len);
        return 1;
    case F_MODEL_PATH:
        if (len > sizeof cfg->model_path) {
            return 0;
        }
        /*@ assert model_path_inside: len <= ABBE_CAN_PATH_MAX; */
        memcpy(cfg->model_path, text, len);
        return 1;
    default:
        return 0;
    }
}

/* The capacity of a string field's member (0 for the others). */
static size_t str_cap(const abbe_can_config_t *cfg, field_id_t id)
{
    return id == F_BUS_INTERFACE ? sizeof cfg->interface : id == F_MODEL_PATH ? sizeof cfg->model_path : 0u;
}

/* An integer or boolean field's value (within the field's range: store checked
 * it) into its member; 0 if the id is not an integer field's (never). */
static int put_int(abbe_can_config_t *cfg, abbe_can_axis_config_t *ax, field_id_t id, long long v)
{
    switch (id) {
    case F_BUS_NODE_ID: cfg->node_id = (uint8_t)v; break;
    case F_BUS_SYNC_COB_ID: cfg->sync_cob_id = (uint32_t)v; break;
    case F_STATUS_ENABLE: cfg->status_enable = (uint8_t)v; break;
    case F_STATUS_COB_ID: cfg->status_cob_id = (uint32_t)v; break;
    case F_STATUS_INFO_COB_ID: cfg->info_cob_id = (uint32_t)v; break;
    case F_STATUS_INFO_PERIOD: cfg->info_period_cycles = (uint16_t)v; break;
    case F_COMMAND_ENABLE: cfg->command_enable = (uint8_t)v; break;
    case F_COMMAND_COB_ID: cfg->command_cob_id = (uint32_t)v; break;
    case F_COMP_FADE_CYCLES: cfg->fade_cycles = (uint16_t)v; break;
    case F_COMP_STALE_CYCLES: cfg->stale_cycles = (uint16_t)v; break;
    case F_COMP_ENABLE_ON_START: cfg->enable_on_start = (uint8_t)v; break;
    case F_TEMP_ENABLE: cfg->temp_enable = (uint8_t)v; break;
    case F_TEMP_COB_ID: cfg->temp_cob_id = (uint32_t)v; break;
    case F_TEMP_STALE_CYCLES: cfg->temp_stale_cycles = (uint16_t)v; break;
    case F_THERMAL_ENABLE: cfg->thermal_enable = (uint8_t)v; break;
    case F_THERMAL_COB_ID: cfg->thermal_cob_id = (uint32_t)v; break;
    case F_THERMAL_CYCLE_US: cfg->cycle_us = (uint32_t)v; break;
    case F_AX_NODE_ID: ax->node_id = (uint8_t)v; break;
    case F_AX_SIGN: ax->sign = (int8_t)v; break;
    case F_AX_CORRECTION_SIGN: ax->correction_sign = (int8_t)v; break;
    case F_AX_TPDO_COB_ID: ax->tpdo_cob_id = (uint32_t)v; break;
    case F_AX_TPDO_DLC: ax->tpdo_dlc = (uint8_t)v; break;
    case F_AX_POSITION_BYTE: ax->position_byte = (uint8_t)v; break;
    case F_AX_STATUSWORD_BYTE: ax->statusword_byte = (int8_t)v; break;
    case F_AX_RPDO_COB_ID: ax->rpdo_cob_id = (uint32_t)v; break;
    case F_AX_RPDO_DLC: ax->rpdo_dlc = (uint8_t)v; break;
    case F_AX_OFFSET_BYTE: ax->offset_byte = (uint8_t)v; break;
    default: return 0;
    }
    return 1;
}

/* A scaled number (already an int32 in the stored unit) into its member; 0 if
 * the id is not a scaled field's (never). */
static int put_scaled(abbe_can_axis_config_t *ax, field_id_t id, int32_t v)
{
    switch (id) {
    case F_AX_ORIGIN: ax->origin_nm = v; break;
    case F_AX_WARN: ax->warn_nm = v; break;
    case F_AX_LIMIT: ax->limit_nm = v; break;
    case F_AX_RATE: ax->rate_nm_per_cycle = v; break;
    case F_AX_DEADBAND: ax->deadband_nm = v; break;
    case F_AX_TEMP: ax->temp_mdegc = v; break;
    default: return 0;
    }
    return 1;
}

/* The one double field. */
static int put_double(abbe_can_axis_config_t *ax, field_id_t id, double v)
{
    if (id != F_AX_INCREMENTS_PER_MM) {
        return 0;
    }
    ax->increments_per_mm = v;
    return 1;
}

/* The field's kind and id disagree (a FIELDS entry wrong): no entry does, the
 * tests parse every field. */
#define FIELD_TABLE_WRONG "internal error: field table"

static int store(parser_t *ps, const field_t *f, abbe_can_axis_config_t *ax, const token_t *tok, unsigned line,
                 const char *field)
{
    abbe_can_config_t *cfg = ps->cfg;
    if (f->kind == V_STR) {
        if (!tok->is_string) {
            return error(ps, line, field, "expected a \"string\"");
        }
        size_t n = strlen(tok->text);
        if (n >= str_cap(cfg, f->id)) {
            return error(ps, line, field, "string too long");
        }
        if (n == 0u) {
            return error(ps, line, field, "must not be empty");
        }
        return put_str(cfg, f->id, tok->text, n) ? ABBE_CAN_OK : error(ps, line, field, FIELD_TABLE_WRONG);
    }
    if (tok->is_string) {
        if (f->kind == V_BOOL) {
            return error(ps, line, field, "expected true or false, not a string");
        }
        return error(ps, line, field, "expected a number, not a string");
    }
    if (f->kind == V_BOOL) {
        long long v;
        if (strcmp(tok->text, "true") == 0) {
            v = 1;
        } else if (strcmp(tok->text, "false") == 0) {
            v = 0;
        } else {
            return error(ps, line, field, "expected true or false");
        }
        return put_int(cfg, ax, f->id, v) ? ABBE_CAN_OK : error(ps, line, field, FIELD_TABLE_WRONG);
    }
    if (f->kind == V_DOUBLE || f->kind == V_SCALED) {
        double v = 0.0;
        int st = abbe_can_toml_number(tok->text, &v);
        if (st == 0) {
            return error(ps, line, field, "expected a number (TOML syntax: 10000, -0.5, 2.6214e4, 1_000)");
        }
        if (st < 0) {
            return error(ps, line, field, "value out of range");
        }
        if (f->kind == V_DOUBLE) {
            return put_double(ax, f->id, v) ? ABBE_CAN_OK : error(ps, line, field, FIELD_TABLE_WRONG);
        }
        double scaled = v * f->scale;
        if (!(scaled > -2147483647.0 && scaled < 2147483647.0)) {
            return error(ps, line, field, "value out of range");
        }
        return put_scaled(ax, f->id, abbe_can_round_sat(scaled)) ? ABBE_CAN_OK
                                                                 : error(ps, line, field, FIELD_TABLE_WRONG);
    }
    long long v = 0;
    int ist = abbe_can_toml_int(tok->text, &v);
    if (ist == 0) {
        return error(ps, line, field, "expected an integer (decimal or 0x hex)");
    }
    if (ist < 0) {
        v = tok->text[0] == '-' ? LLONG_MIN : LLONG_MAX; /* reported as out of range below */
    }
    if (v < f->min || v > f->max) {
        char msg[96] = {0};
        if (f->kind == V_U32) {
            snprintf(msg, sizeof msg, "must be 0x%03llX..0x%03llX", f->min, f->max);
        } else {
            snprintf(msg, sizeof msg, "must be %lld..%lld", f->min, f->max);
        }
        msg[sizeof msg - 1u] = '\0'; /* as field in parse_pair */
        return error(ps, line, field, msg);
    }
    return put_int(cfg, ax, f->id, v) ? ABBE_CAN_OK : error(ps, line, field, FIELD_TABLE_WRONG);
}

static unsigned seen_line(const parser_t *ps, const char *field)
{
    for (unsigned i = 0; i < ps->n_seen && i < MAX_SEEN; i++) { /* n_seen <= MAX_SEEN: the bound, stated */
        if (strcmp(ps->seen_field[i], field) == 0) {
            return ps->seen_line[i];
        }
    }
    return 0;
}

/* The value after "field =" (p at the '='), into field f of base. */
static int set_field(parser_t *ps, const field_t *f, const char *p, unsigned line, const char *field)
{
    /* an axis field is matched in an axis section only: the index is 0..2
     * (the clamp never binds; it states the bound where the proof needs it) */
    unsigned axis = (unsigned)ps->section - AXIS_SECTION0;
    abbe_can_axis_config_t *ax = &ps->cfg->axis[axis < ABBE_AXES ? axis : 0u];
    if (seen_line(ps, field) != 0u) {
        return error(ps, line, field, "set twice");
    }
    token_t tok = {{0}, 0};
    int st;
    p = read_value(ps, skip_space(ps, p + 1), line, field, &tok, &st);
    if (st != ABBE_CAN_OK) {
        return st;
    }
    if (!rest_is_empty(ps, p)) {
        return error(ps, line, field, "unexpected text after the value");
    }
    st = store(ps, f, ax, &tok, line, field);
    if (st != ABBE_CAN_OK) {
        return st;
    }
    if (ps->n_seen < MAX_SEEN) {
        copy_str(ps->seen_field[ps->n_seen], sizeof ps->seen_field[0], field);
        ps->seen_line[ps->n_seen] = line;
        ps->n_seen++;
    }
    return ABBE_CAN_OK;
}

/* "section.key" (or the key alone without a section) into field: a section's
 * name (< 12 characters), '.', a key (< 32 characters) fit its 48 bytes. */
static void join_field(char field[48], const char *section, const char key[32])
{
    size_t n = 0;
    for (size_t i = 0; section != NULL && i < SECTION_NAME_MAX && section[i] != '\0'; i++) {
        field[n++] = section[i];
    }
    if (section != NULL) {
        field[n++] = '.';
    }
    for (size_t i = 0; i < 32u && key[i] != '\0'; i++) {
        field[n++] = key[i];
    }
    field[n] = '\0';
}

static int parse_pair(parser_t *ps, const char *p, unsigned line)
{
    char key[32] = {0};
    size_t n = 0;
    while (p < ps->end && is_key_char(*p)) {
        if (n + 1u >= sizeof key) {
            return error(ps, line, NULL, "key too long");
        }
        key[n++] = *p++;
    }
    key[n] = '\0';
    if (n == 0) {
        return error(ps, line, NULL, "expected key = value, [section] or # comment");
    }
    /*@ split ps->section; */ /* the proof: each section's keys apart (the field table is matched per section) */
    char field[48] = {0};
    join_field(field, ps->section >= 0 ? SECTIONS[ps->section] : NULL, key);
    p = skip_space(ps, p);
    if (p >= ps->end || *p != '=') {
        return error(ps, line, field, "expected '=' after the key");
    }
    if (ps->section < 0) {
        return error(ps, line, key, ps->section == -1 ? "key outside a section: start with [bus] or another section"
                                                      : "keys go into [axis.X], [axis.Y] or [axis.Z]");
    }
    const char *sec = SECTIONS[ps->section];
    int is_axis = (unsigned)ps->section >= AXIS_SECTION0;
    /* the value is read and stored from inside the match: each field's own
     * call, so the proof sees which field (its kind, offset, size) it writes */
    for (unsigned i = 0; i < N_FIELDS; i++) {
        if (strcmp(FIELDS[i].key, key) == 0 && strcmp(FIELDS[i].section, is_axis ? "axis" : sec) == 0) {
            return set_field(ps, &FIELDS[i], p, line, field);
        }
    }
    return error(ps, line, field, "unknown key");
}

static int parse_line(parser_t *ps, const char *line, unsigned lineno)
{
    ps->last_line = lineno;
    const char *p = skip_space(ps, line);
    if (*p == '\0' || *p == '#') {
        return ABBE_CAN_OK;
    }
    if (*p == '[') {
        return parse_header(ps, p, lineno);
    }
    return parse_pair(ps, p, lineno);
}

/* Where a field's problem is: its own line, else its section's header, else the end. */
static unsigned line_of(const parser_t *ps, const char *field)
{
    unsigned l = seen_line(ps, field);
    if (l != 0u) {
        return l;
    }
    char name[48] = {0}; /* field in a buffer longer than every section's name */
    copy_literal(name, sizeof name, field);
    for (unsigned s = 0; s < N_SECTIONS; s++) {
        size_t n = strlen(SECTIONS[s]);
        if (strncmp(name, SECTIONS[s], n) == 0 && name[n] == '.' && ps->section_line[s] != 0u) {
            return ps->section_line[s];
        }
    }
    return ps->last_line;
}

static void resolve_model_path(abbe_can_config_t *cfg, const char *name, parser_t *ps, int *st)
{
    const char *slash = strrchr(name, '/');
    if (cfg->model_path[0] == '/' || slash == NULL) {
        return;
    }
    size_t dir = (size_t)(slash - name) + 1u;
    size_t len = strlen(cfg->model_path);
    if (dir + len + 1u > sizeof cfg->model_path) {
        *st = error(ps, line_of(ps, "model.path"), "model.path", "path too long once joined to the file's directory");
        return;
    }
    memmove(cfg->model_path + dir, cfg->model_path, len + 1u);
    memcpy(cfg->model_path, name, dir);
}

static int finish(parser_t *ps)
{
    abbe_can_config_t *cfg = ps->cfg;
    /* required sections and keys */
    for (unsigned s = 0; s < N_SECTIONS; s++) {
        int axis = s >= AXIS_SECTION0;
        if ((axis || strcmp(SECTIONS[s], "model") == 0) && ps->section_line[s] == 0u) {
            char msg[64] = {0};
            snprintf(msg, sizeof msg, "missing section [%.11s]", SECTIONS[s]);
            msg[sizeof msg - 1u] = '\0'; /* as field in parse_pair */
            return error(ps, ps->last_line, SECTIONS[s], msg);
        }
        for (unsigned i = 0; i < N_FIELDS; i++) {
            const field_t *f = &FIELDS[i];
            if (!f->required || strcmp(f->section, axis ? "axis" : SECTIONS[s]) != 0) {
                continue;
            }
            char field[48] = {0};
            join_field(field, SECTIONS[s], f->key);
            if (seen_line(ps, field) == 0u) {
                return error(ps, ps->section_line[s], field, "missing (required)");
            }
        }
    }
    int st = ABBE_CAN_OK;
    resolve_model_path(cfg, ps->name, ps, &st);
    if (st != ABBE_CAN_OK) {
        return st;
    }
    const char *field = "", *why = "";
    if (abbe_can_config_check(cfg, &field, &why) != ABBE_CAN_OK) {
        return error_of_check(ps, line_of(ps, field), field, why);
    }
    return ABBE_CAN_OK;
}

static void parser_init(parser_t *ps, abbe_can_config_t *cfg, const char *name, abbe_can_config_error_t *err)
{
    memset(ps, 0, sizeof *ps);
    ps->cfg = cfg;
    ps->err = err;
    ps->name = name != NULL ? name : "<config>";
    ps->section = -1;
    abbe_can_config_defaults(cfg);
    if (err != NULL) {
        memset(err, 0, sizeof *err);
    }
}

int abbe_can_config_parse(abbe_can_config_t *cfg, const char *text, size_t len, const char *name,
                          abbe_can_config_error_t *err)
{
    if (cfg == NULL || (text == NULL && len > 0u)) {
        return ABBE_CAN_E_ARG;
    }
    parser_t ps;
    parser_init(&ps, cfg, name, err);
    size_t pos = 0;
    unsigned lineno = 0;
    char line[ABBE_CAN_LINE_MAX];
    ps.end = &line[sizeof line - 1u];
    while (pos < len) {
        /* every byte defined, the last one '\0': the line is a string ending
         * inside the buffer whatever the text (the proof follows the bytes,
         * not the loop's count) */
        memset(line, 0, sizeof line);
        size_t n = 0;
        lineno++;
        while (pos < len && text[pos] != '\n') {
            if (n + 1u >= sizeof line) {
                return error(&ps, lineno, NULL, "line too long");
            }
            if (text[pos] == '\0') {
                return error(&ps, lineno, NULL, "NUL byte in the file");
            }
            line[n++] = text[pos++];
        }
        pos++; /* the newline */
        if (n > 0u && line[n - 1u] == '\r') {
            n--;
        }
        line[n] = '\0';
        int st = parse_line(&ps, line, lineno);
        if (st != ABBE_CAN_OK) {
            return st;
        }
    }
    return finish(&ps);
}


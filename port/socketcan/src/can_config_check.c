/* abbe CAN port: configuration defaults, checks and scaling (portable). */
#include <string.h>

#include "abbe_can.h"
#include "can_internal.h"

void abbe_can_config_defaults(abbe_can_config_t *cfg)
{
    if (cfg == NULL) {
        return;
    }
    memset(cfg, 0, sizeof *cfg);
    memcpy(cfg->interface, "can0", 5);
    cfg->node_id = ABBE_CAN_DEFAULT_NODE_ID;
    cfg->sync_cob_id = ABBE_CAN_SYNC_COB_ID;
    cfg->status_enable = 1;
    cfg->info_period_cycles = 100;
    cfg->command_enable = 1;
    cfg->fade_cycles = 100;
    cfg->stale_cycles = 10;
    cfg->enable_on_start = 1;
    cfg->temp_stale_cycles = 1000;
    cfg->thermal_cob_id = 0x3F0u;
    cfg->cycle_us = 1000u;
    for (unsigned j = 0; j < ABBE_AXES; j++) {
        abbe_can_axis_config_t *ax = &cfg->axis[j];
        ax->sign = 1;
        ax->correction_sign = 1;
        ax->warn_nm = 50000;
        ax->limit_nm = 100000;
        ax->rate_nm_per_cycle = 1000;
        ax->deadband_nm = 1000;
        ax->temp_mdegc = 20000;
        ax->tpdo_dlc = 4;
        ax->rpdo_dlc = 4;
        ax->statusword_byte = ABBE_CAN_NO_BYTE;
    }
}

/* Field names as they appear in the configuration file. */
#define AXIS_FIELDS(A)                                                                    \
    {"axis." A ".node_id", "axis." A ".increments_per_mm", "axis." A ".sign",             \
     "axis." A ".correction_sign", "axis." A ".warn_um", "axis." A ".limit_um",            \
     "axis." A ".rate_um_per_cycle", "axis." A ".deadband_um", "axis." A ".tpdo_cob_id",  \
     "axis." A ".tpdo_dlc", "axis." A ".position_byte", "axis." A ".statusword_byte",      \
     "axis." A ".rpdo_cob_id", "axis." A ".rpdo_dlc", "axis." A ".offset_byte", "axis." A ".temp_c"}
enum {
    F_NODE, F_IPM, F_SIGN, F_CSIGN, F_WARN, F_LIMIT, F_RATE, F_DEADBAND, F_TPDO, F_TPDO_DLC,
    F_POS_BYTE, F_SW_BYTE, F_RPDO, F_RPDO_DLC, F_OFS_BYTE, F_TEMP, F_COUNT
};
static const char *const axis_field[ABBE_AXES][F_COUNT] = {AXIS_FIELDS("X"), AXIS_FIELDS("Y"),
                                                           AXIS_FIELDS("Z")};

static int fail(const char **field, const char **why, const char *f, const char *w)
{
    if (field != NULL) {
        *field = f;
    }
    if (why != NULL) {
        *why = w;
    }
    return ABBE_CAN_E_CONFIG;
}

static int cob_ok(uint32_t id)
{
    return id >= 1u && id <= ABBE_CAN_SFF_MASK;
}

/* Roles in the frame map, for the collision check. */
enum { R_SYNC, R_STATUS, R_INFO, R_COMMAND, R_TEMP, R_THERMAL, R_TPDO, R_RPDO };
static const char *const role_msg[] = {
    "COB-ID already used by bus.sync_cob_id",     "COB-ID already used by status.cob_id",
    "COB-ID already used by status.info_cob_id",  "COB-ID already used by command.cob_id",
    "COB-ID already used by temperature.cob_id",
    "COB-ID already used by the thermal frames (thermal.cob_id .. + 4)", "COB-ID already used by an axis' tpdo_cob_id",
    "COB-ID already used by an axis' rpdo_cob_id",
};

typedef struct {
    uint32_t id;
    int role;
    int axis;
    const char *field;
} map_entry_t;

static int check_axis(const abbe_can_axis_config_t *ax, unsigned j, const char **field, const char **why)
{
    const char *const *f = axis_field[j];
    if (ax->node_id < 1u || ax->node_id > 127u) {
        return fail(field, why, f[F_NODE], "must be a CANopen node id, 1..127");
    }
    /* written as a negated range so a NaN fails too */
    if (!(ax->increments_per_mm > 0.0 && ax->increments_per_mm <= 1e9)) {
        return fail(field, why, f[F_IPM], "must be > 0 and <= 1e9");
    }
    if (ax->sign != 1 && ax->sign != -1) {
        return fail(field, why, f[F_SIGN], "must be 1 or -1");
    }
    if (ax->correction_sign != 1 && ax->correction_sign != -1) {
        return fail(field, why, f[F_CSIGN], "must be 1 or -1");
    }
    if (ax->warn_nm <= 0) {
        return fail(field, why, f[F_WARN], "must be > 0");
    }
    if (ax->limit_nm < ax->warn_nm) {
        return fail(field, why, f[F_LIMIT], "must be >= warn_um");
    }
    if (ax->rate_nm_per_cycle <= 0) {
        return fail(field, why, f[F_RATE], "must be > 0");
    }
    if (ax->deadband_nm < 0) {
        return fail(field, why, f[F_DEADBAND], "must be >= 0");
    }
    if (ax->temp_mdegc < 10 * ABBE_CAN_TEMP_MIN_CDEGC || ax->temp_mdegc > 10 * ABBE_CAN_TEMP_MAX_CDEGC) {
        return fail(field, why, f[F_TEMP], "must be -50..150 (degC), like a temperature frame reading");
    }
    if (!cob_ok(ax->tpdo_cob_id)) {
        return fail(field, why, f[F_TPDO], "must be an 11-bit COB-ID, 0x001..0x7FF");
    }
    if (ax->tpdo_dlc < 4u || ax->tpdo_dlc > 8u) {
        return fail(field, why, f[F_TPDO_DLC], "must be 4..8");
    }
    if ((unsigned)ax->position_byte + 4u > ax->tpdo_dlc) {
        return fail(field, why, f[F_POS_BYTE], "the INT32 position must fit in tpdo_dlc bytes");
    }
    if (ax->statusword_byte != ABBE_CAN_NO_BYTE) {
        if (ax->statusword_byte < 0 || ax->statusword_byte + 2 > (int)ax->tpdo_dlc) {
            return fail(field, why, f[F_SW_BYTE], "the UINT16 statusword must fit in tpdo_dlc bytes");
        }
        if (ax->statusword_byte + 2 > (int)ax->position_byte &&
            ax->statusword_byte < (int)ax->position_byte + 4) {
            return fail(field, why, f[F_SW_BYTE], "overlaps the position bytes");
        }
    }
    if (!cob_ok(ax->rpdo_cob_id)) {
        return fail(field, why, f[F_RPDO], "must be an 11-bit COB-ID, 0x001..0x7FF");
    }
    if (ax->rpdo_dlc < 4u || ax->rpdo_dlc > 8u) {
        return fail(field, why, f[F_RPDO_DLC], "must be 4..8");
    }
    if ((unsigned)ax->offset_byte + 4u > ax->rpdo_dlc) {
        return fail(field, why, f[F_OFS_BYTE], "the INT32 offset must fit in rpdo_dlc bytes");
    }
    return ABBE_CAN_OK;
}

/* Two map entries with the same id: allowed only for shared PDOs. */
static int check_pair(const abbe_can_config_t *cfg, const map_entry_t *a, const map_entry_t *b,
                      const char **field, const char **why)
{
    /* a PDO's entry has its axis (0..2); the test states it for the proof */
    if (a->role == R_TPDO && b->role == R_TPDO && a->axis >= 0 && b->axis >= 0) {
        if (cfg->axis[a->axis].tpdo_dlc != cfg->axis[b->axis].tpdo_dlc) {
            return fail(field, why, axis_field[b->axis][F_TPDO_DLC],
                        "axes sharing a TPDO must have the same tpdo_dlc");
        }
        return ABBE_CAN_OK;
    }
    if (a->role == R_RPDO && b->role == R_RPDO && a->axis >= 0 && b->axis >= 0) {
        const abbe_can_axis_config_t *x = &cfg->axis[a->axis], *y = &cfg->axis[b->axis];
        if (x->rpdo_dlc != y->rpdo_dlc) {
            return fail(field, why, axis_field[b->axis][F_RPDO_DLC],
                        "axes sharing an RPDO must have the same rpdo_dlc");
        }
        if (x->offset_byte + 4 > y->offset_byte && y->offset_byte + 4 > x->offset_byte) {
            return fail(field, why, axis_field[b->axis][F_OFS_BYTE],
                        "overlaps the offset of another axis in the same RPDO");
        }
        return ABBE_CAN_OK;
    }
    return fail(field, why, b->field, role_msg[a->role]);
}

int abbe_can_config_check(abbe_can_config_t *cfg, const char **field, const char **why)
{
    if (cfg == NULL) {
        return fail(field, why, "", "no configuration");
    }
    if (cfg->interface[0] == '\0' || memchr(cfg->interface, '\0', sizeof cfg->interface) == NULL) {
        return fail(field, why, "bus.interface", "must be a non-empty interface name of < 16 characters");
    }
    if (memchr(cfg->model_path, '\0', sizeof cfg->model_path) == NULL) {
        return fail(field, why, "model.path", "path too long");
    }
    if (cfg->node_id < 1u || cfg->node_id > 127u) {
        return fail(field, why, "bus.node_id", "must be a CANopen node id, 1..127");
    }
    if (cfg->status_cob_id == 0u) {
        cfg->status_cob_id = ABBE_CAN_TPDO1_BASE + cfg->node_id;
    }
    if (cfg->info_cob_id == 0u) {
        cfg->info_cob_id = ABBE_CAN_TPDO2_BASE + cfg->node_id;
    }
    if (cfg->command_cob_id == 0u) {
        cfg->command_cob_id = ABBE_CAN_RPDO1_BASE + cfg->node_id;
    }
    if (cfg->temp_cob_id == 0u) {
        cfg->temp_cob_id = ABBE_CAN_RPDO2_BASE + cfg->node_id;
    }
    if (!cob_ok(cfg->sync_cob_id)) {
        return fail(field, why, "bus.sync_cob_id", "must be an 11-bit COB-ID, 0x001..0x7FF");
    }
    if (!cob_ok(cfg->status_cob_id)) {
        return fail(field, why, "status.cob_id", "must be an 11-bit COB-ID, 0x001..0x7FF");
    }
    if (!cob_ok(cfg->info_cob_id)) {
        return fail(field, why, "status.info_cob_id", "must be an 11-bit COB-ID, 0x001..0x7FF");
    }
    if (!cob_ok(cfg->command_cob_id)) {
        return fail(field, why, "command.cob_id", "must be an 11-bit COB-ID, 0x001..0x7FF");
    }
    if (!cob_ok(cfg->temp_cob_id)) {
        return fail(field, why, "temperature.cob_id", "must be an 11-bit COB-ID, 0x001..0x7FF");
    }
    if (cfg->temp_enable > 1u) {
        return fail(field, why, "temperature.enable", "must be true or false");
    }
    if (cfg->thermal_enable > 1u) {
        return fail(field, why, "thermal.enable", "must be true or false");
    }
    if (!cob_ok(cfg->thermal_cob_id) || cfg->thermal_cob_id + ABBE_CAN_THERMAL_FRAMES - 1u > ABBE_CAN_SFF_MASK) {
        return fail(field, why, "thermal.cob_id", "must be an 11-bit COB-ID, 0x001..0x7FB (5 frames from it)");
    }
    if (cfg->cycle_us < 100u || cfg->cycle_us > 1000000u) {
        return fail(field, why, "thermal.cycle_us", "must be the SYNC period, 100..1000000 us");
    }
    if (cfg->fade_cycles < 1u) {
        return fail(field, why, "compensator.fade_cycles", "must be >= 1");
    }
    if (cfg->stale_cycles < 1u) {
        return fail(field, why, "compensator.stale_cycles", "must be >= 1");
    }
    for (unsigned j = 0; j < ABBE_AXES; j++) {
        abbe_can_axis_config_t *ax = &cfg->axis[j];
        if (ax->node_id >= 1u && ax->node_id <= 127u) {
            if (ax->tpdo_cob_id == 0u) {
                ax->tpdo_cob_id = ABBE_CAN_TPDO1_BASE + ax->node_id;
            }
            if (ax->rpdo_cob_id == 0u) {
                ax->rpdo_cob_id = ABBE_CAN_RPDO1_BASE + ax->node_id;
            }
        }
        int st = check_axis(ax, j, field, why);
        if (st != ABBE_CAN_OK) {
            return st;
        }
    }

    map_entry_t map[5 + ABBE_CAN_THERMAL_FRAMES + 2 * ABBE_AXES];
    for (unsigned i = 0; i < sizeof map / sizeof map[0]; i++) { /* every entry defined, the unused ones too: the proof does not count n */
        map[i] = (map_entry_t){0u, R_SYNC, -1, ""};
    }
    unsigned n = 0;
    map[n++] = (map_entry_t){cfg->sync_cob_id, R_SYNC, -1, "bus.sync_cob_id"};
    if (cfg->status_enable) {
        map[n++] = (map_entry_t){cfg->status_cob_id, R_STATUS, -1, "status.cob_id"};
    }
    if (cfg->info_period_cycles > 0u) {
        map[n++] = (map_entry_t){cfg->info_cob_id, R_INFO, -1, "status.info_cob_id"};
    }
    if (cfg->command_enable) {
        map[n++] = (map_entry_t){cfg->command_cob_id, R_COMMAND, -1, "command.cob_id"};
    }
    if (cfg->temp_enable) {
        map[n++] = (map_entry_t){cfg->temp_cob_id, R_TEMP, -1, "temperature.cob_id"};
    }
    for (unsigned g = 0; cfg->thermal_enable && g < ABBE_CAN_THERMAL_FRAMES; g++) {
        map[n++] = (map_entry_t){cfg->thermal_cob_id + g, R_THERMAL, -1, "thermal.cob_id"};
    }
    for (int j = 0; j < (int)ABBE_AXES; j++) {
        map[n++] = (map_entry_t){cfg->axis[j].tpdo_cob_id, R_TPDO, j, axis_field[j][F_TPDO]};
    }
    for (int j = 0; j < (int)ABBE_AXES; j++) {
        map[n++] = (map_entry_t){cfg->axis[j].rpdo_cob_id, R_RPDO, j, axis_field[j][F_RPDO]};
    }
    for (unsigned b = 1; b < n; b++) {
        for (unsigned a = 0; a < b; a++) {
            if (map[a].id == map[b].id) {
                int st = check_pair(cfg, &map[a], &map[b], field, why);
                if (st != ABBE_CAN_OK) {
                    return st;
                }
            }
        }
    }
    if (field != NULL) {
        *field = "";
    }
    if (why != NULL) {
        *why = "";
    }
    return ABBE_CAN_OK;
}

/* round half away from zero, saturated to int32; NaN gives 0 */
int32_t abbe_can_round_sat(double v)
{
    double r = v < 0.0 ? v - 0.5 : v + 0.5;
    if (r >= 2147483648.0) {
        return INT32_MAX;
    }
    if (r <= -2147483649.0) {
        return INT32_MIN;
    }
    if (!(r > -2147483649.0)) { /* NaN fails every comparison */
        return 0;
    }
    return (int32_t)r; /* truncation toward zero completes the rounding */
}

int32_t abbe_can_incr_to_nm(const abbe_can_axis_config_t *ax, int32_t incr)
{
    if (ax == NULL || !(ax->increments_per_mm > 0.0)) {
        return 0;
    }
    double nm = (double)ax->origin_nm + (double)ax->sign * (double)incr * 1e6 / ax->increments_per_mm;
    return abbe_can_round_sat(nm);
}

int32_t abbe_can_nm_to_incr(const abbe_can_axis_config_t *ax, int32_t corr_nm)
{
    if (ax == NULL) {
        return 0;
    }
    int32_t mag = abbe_can_round_sat((double)corr_nm * ax->increments_per_mm / 1e6);
    if (ax->sign < 0) {
        return mag == INT32_MIN ? INT32_MAX : -mag;
    }
    return mag;
}

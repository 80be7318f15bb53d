/* abbe grblHAL plugin glue: the $ settings (enable, segment deviation
 * bound, maximum correction; docs/grblhal.md), kept in grblHAL's
 * non-volatile settings area. grblHAL's settings load is where the table to
 * run is chosen (abbe_plugin_boot_table): before any motion. */
#include "grbl/hal.h"
#include "grbl/nvs_buffer.h"
#include "grbl/settings.h"

#include "abbe_grblhal.h"
#include "abbe_grblhal_glue.h"

#define SETTING_ENABLE ((setting_id_t)(ABBE_GRBLHAL_SETTING_BASE))
#define SETTING_DEVIATION ((setting_id_t)(ABBE_GRBLHAL_SETTING_BASE + 1))
#define SETTING_LIMIT ((setting_id_t)(ABBE_GRBLHAL_SETTING_BASE + 2))

/* What is stored in grblHAL's non-volatile settings area. */
typedef struct {
    uint8_t enable;
    float max_dev_um;
    float limit_um;
} abbe_nvs_settings_t;

static abbe_nvs_settings_t cfg;
static nvs_address_t nvs_address;
static bool booted;

static void apply_settings(void)
{
    abbe_gh_params_t p = abbe_plugin.params;
    p.max_dev_um = cfg.max_dev_um;
    p.limit_um = cfg.limit_um;
    if (abbe_gh_set_params(&abbe_plugin, &p) != ABBE_OK)
        abbe_plugin_queue_message("abbe: settings out of range, the previous ones stay", true);
    if ((cfg.enable != 0) != (abbe_plugin.enabled != 0))
        (void)abbe_gh_set_enabled(&abbe_plugin, cfg.enable);
}

static status_code_t set_enable(setting_id_t id, uint_fast16_t value)
{
    (void)id;
    cfg.enable = value ? 1 : 0;
    apply_settings();
    return Status_OK;
}

static uint32_t get_enable(setting_id_t id)
{
    (void)id;
    return cfg.enable;
}

static status_code_t set_float(setting_id_t id, float value)
{
    abbe_nvs_settings_t old = cfg;
    if (id == SETTING_DEVIATION)
        cfg.max_dev_um = value;
    else
        cfg.limit_um = value;
    abbe_gh_params_t p = abbe_plugin.params;
    p.max_dev_um = cfg.max_dev_um;
    p.limit_um = cfg.limit_um;
    if (abbe_gh_set_params(&abbe_plugin, &p) != ABBE_OK) {
        cfg = old;
        return Status_SettingValueOutOfRange;
    }
    return Status_OK;
}

static float get_float(setting_id_t id)
{
    return id == SETTING_DEVIATION ? cfg.max_dev_um : cfg.limit_um;
}

static const setting_group_detail_t abbe_groups[] = {
    {Group_Root, Group_Kinematics, "abbe compensation", NULL},
};

static const setting_detail_t abbe_settings[] = {
    {SETTING_ENABLE, Group_Kinematics, "abbe compensation enable", NULL, Format_Bool, NULL, NULL, NULL,
     Setting_NonCoreFn, set_enable, get_enable, NULL, {0}},
    {SETTING_DEVIATION, Group_Kinematics, "abbe segment deviation bound", "um", Format_Decimal, "##0.00", "0.01",
     "100", Setting_NonCoreFn, set_float, get_float, NULL, {0}},
    {SETTING_LIMIT, Group_Kinematics, "abbe maximum correction", "um", Format_Decimal, "###0.0", "1", "2000",
     Setting_NonCoreFn, set_float, get_float, NULL, {0}},
};

static const setting_descr_t abbe_descriptions[] = {
    {SETTING_ENABLE, "Geometric error compensation (abbe table): on / off. Switching fades the correction in or "
                     "out over 32 segments."},
    {SETTING_DEVIATION, "Largest deviation of the correction from the model along a segment, um. Lines are split "
                        "into segments of sqrt(8 x bound / curvature of the table)."},
    {SETTING_LIMIT, "Largest correction per axis, um. Beyond it the compensation faults and fades out."},
};

static void abbe_settings_save(void)
{
    hal.nvs.memcpy_to_nvs(nvs_address, (uint8_t *)&cfg, sizeof cfg, true);
}

static void abbe_settings_restore(void)
{
    abbe_gh_params_t p;
    abbe_gh_default_params(&p);
    cfg.enable = 1;
    cfg.max_dev_um = p.max_dev_um;
    cfg.limit_um = p.limit_um;
    hal.nvs.memcpy_to_nvs(nvs_address, (uint8_t *)&cfg, sizeof cfg, true);
}

static void abbe_settings_load(void)
{
    if (!booted) { /* grblHAL's settings are in RAM now: choose the table */
        abbe_gh_params_t p;
        abbe_gh_default_params(&p);
        abbe_plugin_boot_table(&p, true);
        booted = true;
    }
    if (hal.nvs.memcpy_from_nvs((uint8_t *)&cfg, nvs_address, sizeof cfg, true) != NVS_TransferResult_OK)
        abbe_settings_restore();
    apply_settings();
}

static setting_details_t setting_details = {
    .groups = abbe_groups,
    .n_groups = sizeof(abbe_groups) / sizeof(setting_group_detail_t),
    .settings = abbe_settings,
    .n_settings = sizeof(abbe_settings) / sizeof(setting_detail_t),
    .descriptions = abbe_descriptions,
    .n_descriptions = sizeof(abbe_descriptions) / sizeof(setting_descr_t),
    .save = abbe_settings_save,
    .load = abbe_settings_load,
    .restore = abbe_settings_restore,
};

void abbe_plugin_settings_init(const abbe_gh_params_t *p)
{
    cfg.enable = 1;
    cfg.max_dev_um = p->max_dev_um;
    cfg.limit_um = p->limit_um;

    if ((nvs_address = nvs_alloc(sizeof(abbe_nvs_settings_t))))
        settings_register(&setting_details);
    else { /* no settings area: the compiled-in table, enabled with the defaults */
        abbe_plugin_boot_table(p, false);
        booted = true;
        (void)abbe_gh_set_enabled(&abbe_plugin, 1);
    }
}

bool abbe_plugin_enable_setting(void)
{
    return cfg.enable != 0;
}

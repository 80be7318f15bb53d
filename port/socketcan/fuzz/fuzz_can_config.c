/* libFuzzer harness: the CAN port's configuration file parser
 * (abbe_can_config_parse, docs/can.md "Configuration") on arbitrary text.
 *
 * Checked beyond "no sanitizer report":
 *   - the result is ABBE_CAN_OK or ABBE_CAN_E_CONFIG, nothing else;
 *   - a refusal names the file, a line that exists (0 only for no line), a
 *     NUL-terminated field and a non-empty message, and formats as
 *     "FILE:LINE: field 'F': message" (or without the parts that do not apply);
 *   - an accepted file gives a configuration that abbe_can_config_check()
 *     accepts again unchanged, that starts a node, whose COB-IDs are 11-bit
 *     and unique where the map needs them, and whose values are in the
 *     documented ranges;
 *   - the same text parses to the same bytes twice (no state left behind).
 */
#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "abbe_can.h"
#include "abbe_can_config.h"

#define CHECK(cond)                                                                             \
    do {                                                                                        \
        if (!(cond)) {                                                                          \
            fprintf(stderr, "fuzz_can_config: check failed: %s (line %d)\n", #cond, __LINE__);   \
            abort();                                                                            \
        }                                                                                       \
    } while (0)

#define NAME "/etc/abbe/can.toml"

static abbe_can_node_t g_node;

static int cob_ok(uint32_t id)
{
    return id >= 1u && id <= 0x7FFu;
}

static void check_accepted(const abbe_can_config_t *c)
{
    abbe_can_config_t again = *c;
    const char *field = NULL, *why = NULL;
    CHECK(abbe_can_config_check(&again, &field, &why) == ABBE_CAN_OK);
    CHECK(memcmp(&again, c, sizeof again) == 0); /* already resolved: the check changes nothing */
    CHECK(field != NULL && why != NULL && field[0] == '\0' && why[0] == '\0');
    CHECK(abbe_can_node_init(&g_node, c) == ABBE_CAN_OK);

    CHECK(memchr(c->interface, '\0', sizeof c->interface) != NULL && c->interface[0] != '\0');
    CHECK(memchr(c->model_path, '\0', sizeof c->model_path) != NULL && c->model_path[0] != '\0');
    CHECK(c->node_id >= 1u && c->node_id <= 127u);
    CHECK(cob_ok(c->sync_cob_id) && cob_ok(c->status_cob_id) && cob_ok(c->info_cob_id) &&
          cob_ok(c->command_cob_id) && cob_ok(c->temp_cob_id));
    CHECK(c->fade_cycles >= 1u && c->stale_cycles >= 1u);
    CHECK(c->status_enable <= 1u && c->command_enable <= 1u && c->enable_on_start <= 1u && c->temp_enable <= 1u);
    for (unsigned j = 0; j < ABBE_AXES; j++) {
        const abbe_can_axis_config_t *a = &c->axis[j];
        CHECK(a->node_id >= 1u && a->node_id <= 127u);
        CHECK(isfinite(a->increments_per_mm) && a->increments_per_mm > 0.0 && a->increments_per_mm <= 1e9);
        CHECK((a->sign == 1 || a->sign == -1) && (a->correction_sign == 1 || a->correction_sign == -1));
        CHECK(a->warn_nm > 0 && a->limit_nm >= a->warn_nm && a->rate_nm_per_cycle > 0 && a->deadband_nm >= 0);
        CHECK(a->temp_mdegc >= -50000 && a->temp_mdegc <= 150000);
        CHECK(cob_ok(a->tpdo_cob_id) && cob_ok(a->rpdo_cob_id));
        CHECK(a->tpdo_dlc >= 4u && a->tpdo_dlc <= 8u && a->position_byte + 4u <= a->tpdo_dlc);
        CHECK(a->rpdo_dlc >= 4u && a->rpdo_dlc <= 8u && a->offset_byte + 4u <= a->rpdo_dlc);
        CHECK(a->statusword_byte == ABBE_CAN_NO_BYTE ||
              (a->statusword_byte >= 0 && a->statusword_byte + 2 <= (int)a->tpdo_dlc));
        /* a TPDO or RPDO id is no other role's id */
        const uint32_t ids[2] = {a->tpdo_cob_id, a->rpdo_cob_id};
        for (unsigned k = 0; k < 2; k++) {
            CHECK(ids[k] != c->sync_cob_id);
            CHECK(!c->status_enable || ids[k] != c->status_cob_id);
            CHECK(c->info_period_cycles == 0u || ids[k] != c->info_cob_id);
            CHECK(!c->command_enable || ids[k] != c->command_cob_id);
            CHECK(!c->temp_enable || ids[k] != c->temp_cob_id);
        }
        for (unsigned i = 0; i < ABBE_AXES; i++) {
            CHECK(c->axis[i].tpdo_cob_id != a->rpdo_cob_id);
        }
    }
}

static void check_refused(const abbe_can_config_error_t *e, const uint8_t *data, size_t size)
{
    unsigned lines = 1;
    for (size_t i = 0; i < size; i++) {
        lines += data[i] == '\n';
    }
    CHECK(strcmp(e->file, NAME) == 0);
    CHECK(e->line <= lines);
    CHECK(memchr(e->field, '\0', sizeof e->field) != NULL);
    CHECK(memchr(e->message, '\0', sizeof e->message) != NULL && e->message[0] != '\0');
    char msg[ABBE_CAN_PATH_MAX + 320];
    int n = abbe_can_config_error_format(e, msg, sizeof msg);
    CHECK(n > 0 && (size_t)n < sizeof msg);
    char want[ABBE_CAN_PATH_MAX + 96];
    if (e->line > 0u) {
        snprintf(want, sizeof want, "%s:%u: ", NAME, e->line);
    } else {
        snprintf(want, sizeof want, "%s: ", NAME);
    }
    CHECK(strncmp(msg, want, strlen(want)) == 0);
    if (e->field[0] != '\0') {
        CHECK(strncmp(msg + strlen(want), "field '", 7) == 0);
    }
}

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    if (size > ABBE_CAN_CONFIG_MAX) {
        return 0; /* abbe_can_config_load refuses larger files before parsing */
    }
    static abbe_can_config_t c1, c2;
    abbe_can_config_error_t e1, e2;
    memset(&c1, 0xA5, sizeof c1);
    memset(&c2, 0x5A, sizeof c2);
    int st = abbe_can_config_parse(&c1, (const char *)data, size, NAME, &e1);
    CHECK(st == ABBE_CAN_OK || st == ABBE_CAN_E_CONFIG);
    int st2 = abbe_can_config_parse(&c2, (const char *)data, size, NAME, &e2);
    CHECK(st2 == st);
    if (st == ABBE_CAN_OK) {
        CHECK(memcmp(&c1, &c2, sizeof c1) == 0);
        check_accepted(&c1);
    } else {
        CHECK(e1.line == e2.line && strcmp(e1.field, e2.field) == 0 && strcmp(e1.message, e2.message) == 0);
        check_refused(&e1, data, size);
    }
    return 0;
}

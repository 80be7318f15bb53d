/* abbe CAN port: the configuration file (host): read it whole into a bounded
 * buffer and hand the text to the parser (can_config_parse.c); the error's
 * one-line form. */
#include <errno.h>
#include <stdio.h>
#include <string.h>

#include "abbe_can_config.h"

/* An error before there is text to parse: the configuration is the defaults
 * and *err names the file (line 0), as the parser would. */
static int file_error(abbe_can_config_t *cfg, const char *path, abbe_can_config_error_t *err, const char *message)
{
    abbe_can_config_defaults(cfg);
    if (err != NULL) {
        memset(err, 0, sizeof *err);
        snprintf(err->file, sizeof err->file, "%s", path);
        snprintf(err->message, sizeof err->message, "%s", message);
    }
    return ABBE_CAN_E_CONFIG;
}

int abbe_can_config_load(abbe_can_config_t *cfg, const char *path, abbe_can_config_error_t *err)
{
    if (cfg == NULL || path == NULL) {
        return ABBE_CAN_E_ARG;
    }
    FILE *fp = fopen(path, "rb");
    if (fp == NULL) {
        char msg[160];
        snprintf(msg, sizeof msg, "cannot open: %s", strerror(errno));
        return file_error(cfg, path, err, msg);
    }
    char text[ABBE_CAN_CONFIG_MAX + 1u];
    size_t len = fread(text, 1, sizeof text, fp);
    int read_error = ferror(fp);
    int saved_errno = errno;
    fclose(fp);
    if (read_error) {
        char msg[160];
        snprintf(msg, sizeof msg, "read error: %s", strerror(saved_errno));
        return file_error(cfg, path, err, msg);
    }
    if (len > ABBE_CAN_CONFIG_MAX) {
        return file_error(cfg, path, err, "file too large (limit 32 KiB)");
    }
    return abbe_can_config_parse(cfg, text, len, path, err);
}

int abbe_can_config_error_format(const abbe_can_config_error_t *err, char *buf, size_t size)
{
    if (err == NULL || buf == NULL) {
        return -1;
    }
    char where[ABBE_CAN_PATH_MAX + 16];
    if (err->line > 0u) {
        snprintf(where, sizeof where, "%s:%u", err->file, err->line);
    } else {
        snprintf(where, sizeof where, "%s", err->file);
    }
    if (err->field[0] != '\0') {
        return snprintf(buf, size, "%s: field '%s': %s", where, err->field, err->message);
    }
    return snprintf(buf, size, "%s: %s", where, err->message);
}

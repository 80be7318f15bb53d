/* abbe grblHAL plugin glue: an uploaded table kept in non-volatile storage
 * for the next start-up, and the table chosen at start-up (a stored one, the
 * compiled-in one, or none; docs/grblhal.md "Stored tables"). The
 * storage header's format is the core's (abbe_gh_store_header / _parse). */
#include <stdio.h>
#include <string.h>

#include "grbl/hal.h"
#include "grbl/nvs_buffer.h"

#include "abbe_grblhal_glue.h"

#ifdef ABBE_GRBLHAL_BUILTIN
#include "abbe_model.h" /* abbe table cgen MODEL -o DIR */
#endif

/* Physical non-volatile storage the driver provides, bytes, when it does not
 * say (hal.nvs.size_max == 0). Uploaded tables are kept above grblHAL's
 * buffered area (docs/grblhal.md); 0: none, uploads last until a restart.
 * The Simulator's EEPROM.DAT is 4096 bytes (its build sets this). */
#ifndef ABBE_GRBLHAL_NVS_BYTES
#define ABBE_GRBLHAL_NVS_BYTES 0
#endif

static abbe_status_t boot_status = ABBE_OK;
static char boot_text[144]; /* where the running table came from at start-up ($ABBE) */

/* Uploaded tables are kept in the physical NVS above the area grblHAL buffers
 * in RAM (NVS_SIZE, or up to NVS_SIZE_MAX when the driver reports a larger
 * hal.nvs.size_max): grblHAL neither reads nor writes there, and a table does
 * not fit in its settings area. Needs byte-addressable storage (EEPROM, FRAM:
 * memcpy_to_nvs); a driver with flash-emulated NVS has none. */
static nvs_io_t *store_io(void)
{
    nvs_io_t *io = nvs_buffer_get_physical();
    return io != NULL && io->type != NVS_Flash && io->type != NVS_None && io->memcpy_to_nvs != NULL &&
                   io->memcpy_from_nvs != NULL
               ? io
               : NULL;
}

static uint32_t store_address(void)
{
    uint32_t buffered = NVS_SIZE;
    if (hal.nvs.size_max > NVS_SIZE)
        buffered = hal.nvs.size_max < NVS_SIZE_MAX ? hal.nvs.size_max : NVS_SIZE_MAX;
    return (buffered + 3u) & ~3u;
}

uint32_t abbe_plugin_store_capacity(void)
{
    uint32_t physical = hal.nvs.size_max ? hal.nvs.size_max : (uint32_t)(ABBE_GRBLHAL_NVS_BYTES);
    uint32_t at = store_address() + ABBE_GH_STORE_HEADER_BYTES;
    if (store_io() == NULL || physical <= at)
        return 0u;
    return physical - at;
}

/* CRC-32 of n bytes of storage from addr, read in small pieces. */
static uint32_t store_crc(nvs_io_t *io, uint32_t addr, uint32_t n)
{
    uint8_t buf[64];
    uint32_t crc = 0u;
    while (n > 0u) {
        uint32_t k = n < sizeof buf ? n : (uint32_t)sizeof buf;
        (void)io->memcpy_from_nvs(buf, addr, k, false);
        crc = abbe_crc32(crc, buf, k);
        addr += k;
        n -= k;
    }
    return crc;
}

/* Keep the blob just committed for the next start-up: invalidate the header,
 * write the blob, write the header, read it all back. Returns false with *why. */
bool abbe_plugin_store_table(const uint8_t *blob, uint32_t size, uint32_t crc, const char **why)
{
    nvs_io_t *io = store_io();
    uint32_t cap = abbe_plugin_store_capacity(), at = store_address();
    uint8_t header[ABBE_GH_STORE_HEADER_BYTES];
    static char text[96];
    if (cap == 0u) {
        *why = "this build has no non-volatile storage for tables (ABBE_GRBLHAL_NVS_BYTES)";
        return false;
    }
    if (size > cap) {
        snprintf(text, sizeof text, "%lu bytes, the table storage holds %lu", (unsigned long)size,
                 (unsigned long)cap);
        *why = text;
        return false;
    }
    memset(header, 0, sizeof header);
    (void)io->memcpy_to_nvs(at, header, sizeof header, false);
    (void)io->memcpy_to_nvs(at + ABBE_GH_STORE_HEADER_BYTES, (uint8_t *)blob, size, false);
    abbe_gh_store_header(header, size, crc);
    (void)io->memcpy_to_nvs(at, header, sizeof header, false);
    uint8_t back[ABBE_GH_STORE_HEADER_BYTES];
    (void)io->memcpy_from_nvs(back, at, sizeof back, false);
    if (memcmp(back, header, sizeof header) != 0 || store_crc(io, at + ABBE_GH_STORE_HEADER_BYTES, size) != crc) {
        *why = "read-back differs from what was written";
        return false;
    }
    return true;
}

void abbe_plugin_store_erase(void)
{
    nvs_io_t *io = store_io();
    uint8_t header[ABBE_GH_STORE_HEADER_BYTES];
    if (abbe_plugin_store_capacity() == 0u)
        return;
    memset(header, 0, sizeof header);
    (void)io->memcpy_to_nvs(store_address(), header, sizeof header, false);
}

/* The table to run from start-up: a stored one whose header, CRC-32 and
 * library validation pass; else the compiled-in one; else none. Runs once,
 * before any motion (settings load), so the choice causes no jump. */
void abbe_plugin_boot_table(const abbe_gh_params_t *p, bool try_stored)
{
    const char *why = "";
    char stored_why[64] = "";
    uint32_t size = 0, crc = 0;
    if (try_stored && abbe_plugin_store_capacity() > 0u) {
        nvs_io_t *io = store_io();
        uint8_t header[ABBE_GH_STORE_HEADER_BYTES];
        (void)io->memcpy_from_nvs(header, store_address(), sizeof header, false);
        abbe_gh_store_t st = abbe_gh_store_parse(header, abbe_plugin_store_capacity(), &size, &crc, &why);
        if (st == ABBE_GH_STORE_VALID) {
            uint8_t *buf = abbe_gh_boot_buffer(&abbe_plugin);
            (void)io->memcpy_from_nvs(buf, store_address() + ABBE_GH_STORE_HEADER_BYTES, size, false);
            abbe_status_t ls;
            if (abbe_crc32(0u, buf, size) != crc)
                why = "CRC-32 of the stored bytes differs from the header's";
            else if ((ls = abbe_gh_init(&abbe_plugin, p, buf, size)) != ABBE_OK)
                why = abbe_strerror(ls);
            else {
                snprintf(boot_text, sizeof boot_text, "stored table %08lX (%lu bytes) in use",
                         (unsigned long)abbe_model_crc(abbe_gh_model(&abbe_plugin)), (unsigned long)size);
                char msg[ABBE_PLUGIN_MESSAGE_BYTES];
                snprintf(msg, sizeof msg, "abbe: %s", boot_text);
                abbe_plugin_queue_message(msg, false);
                return;
            }
        }
        if (st != ABBE_GH_STORE_NONE)
            snprintf(stored_why, sizeof stored_why, "%s", why);
    }
#ifdef ABBE_GRBLHAL_BUILTIN
    boot_status = abbe_gh_init(&abbe_plugin, p, abbe_model_blob, abbe_model_blob_size);
    if (boot_status != ABBE_OK)
        (void)abbe_gh_init(&abbe_plugin, p, NULL, 0);
#else
    (void)abbe_gh_init(&abbe_plugin, p, NULL, 0);
#endif
    const abbe_model_t *m = abbe_gh_model(&abbe_plugin);
    if (stored_why[0]) {
        if (m != NULL)
            snprintf(boot_text, sizeof boot_text, "stored table refused (%s); compiled-in table %08lX in use",
                     stored_why, (unsigned long)abbe_model_crc(m));
        else
            snprintf(boot_text, sizeof boot_text, "stored table refused (%s); no table", stored_why);
        char msg[ABBE_PLUGIN_MESSAGE_BYTES];
        snprintf(msg, sizeof msg, "abbe: %s", boot_text);
        abbe_plugin_queue_message(msg, true); /* a stored table was refused */
    } else if (m != NULL)
        snprintf(boot_text, sizeof boot_text, "compiled-in table %08lX in use", (unsigned long)abbe_model_crc(m));
    else
        snprintf(boot_text, sizeof boot_text, "no table");
}

const char *abbe_plugin_boot_text(void)
{
    return boot_text;
}

abbe_status_t abbe_plugin_boot_status(void)
{
    return boot_status;
}

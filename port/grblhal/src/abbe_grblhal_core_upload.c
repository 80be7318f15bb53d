/* abbe grblHAL plugin core, the bytes that come in: a table uploaded in
 * chunks ($ABBEU), checked and queued for the next segment, and the header
 * of a table kept in non-volatile storage (include/abbe_grblhal_core.h;
 * tests/proofs/grblhal.c proves this intake). C99, no heap, no I/O. */
#include <string.h>

#include "abbe_grblhal_core_private.h"

static void put_le32(uint8_t *p, uint32_t v)
{
    for (unsigned k = 0; k < 4u; k++) {
        p[k] = (uint8_t)(v >> (8u * k));
    }
}

static uint32_t get_le32(const uint8_t *p)
{
    return (uint32_t)p[0] | ((uint32_t)p[1] << 8) | ((uint32_t)p[2] << 16) | ((uint32_t)p[3] << 24);
}

void abbe_gh_store_header(uint8_t out[ABBE_GH_STORE_HEADER_BYTES], uint32_t size, uint32_t crc)
{
    put_le32(out, ABBE_GH_STORE_MAGIC);
    put_le32(out + 4, size);
    put_le32(out + 8, crc);
    put_le32(out + 12, abbe_crc32(0u, out, 12u));
}

abbe_gh_store_t abbe_gh_store_parse(const uint8_t in[ABBE_GH_STORE_HEADER_BYTES], uint32_t capacity,
                                    uint32_t *size, uint32_t *crc, const char **why)
{
    static const char *const none = "";
    *why = none;
    uint32_t magic = get_le32(in);
    if (magic == 0u || magic == 0xFFFFFFFFu) {
        return ABBE_GH_STORE_NONE; /* invalidated / erased */
    }
    if (magic != ABBE_GH_STORE_MAGIC) {
        *why = "no abbe table header (magic)";
        return ABBE_GH_STORE_CORRUPT;
    }
    if (get_le32(in + 12) != abbe_crc32(0u, in, 12u)) {
        *why = "header CRC-32 mismatch";
        return ABBE_GH_STORE_CORRUPT;
    }
    uint32_t n = get_le32(in + 4);
    uint32_t max = capacity < ABBE_GH_TABLE_MAX_BYTES ? capacity : ABBE_GH_TABLE_MAX_BYTES;
    if (n < 16u || n > max) {
        *why = "stored size out of range";
        return ABBE_GH_STORE_CORRUPT;
    }
    *size = n;
    *crc = get_le32(in + 8);
    return ABBE_GH_STORE_VALID;
}

/* Append text / an unsigned decimal at w, never past end (the buffer's end: the
 * text is cut there); return the new end, NUL-terminated. w < end. */
static char *put_text(char *w, const char *end, const char *text)
{
    while (*text != '\0' && w + 1 < end) {
        *w = *text;
        w++;
        text++;
    }
    *w = '\0';
    return w;
}

static char *put_u32(char *w, const char *end, uint32_t v)
{
    char digits[10] = {0}; /* 4294967295: ten digits */
    unsigned n = 0u;
    do {
        digits[n] = (char)('0' + (char)(v % 10u));
        n++;
        v /= 10u;
    } while (v != 0u && n < 10u);
    while (n > 0u && w + 1 < end) {
        n--;
        *w = digits[n];
        w++;
    }
    *w = '\0';
    return w;
}

abbe_status_t abbe_gh_upload_begin(abbe_gh_t *gh, uint32_t size, uint32_t crc, const char **why)
{
    static const char *const none = "";
    *why = none;
    if (gh->pending != NO_SLOT) {
        *why = "the previous upload is not in use yet (it takes over at the next segment: move first)";
        return ABBE_E_ARG;
    }
    if (size < 16u || size > ABBE_GH_TABLE_MAX_BYTES) {
        /* "table of 9000 bytes: this build takes 16 to 8192 bytes" */
        char *w = gh->stage.why;
        const char *end = gh->stage.why + sizeof gh->stage.why;
        w = put_text(w, end, "table of ");
        w = put_u32(w, end, size);
        w = put_text(w, end, " bytes: this build takes 16 to ");
        w = put_u32(w, end, (uint32_t)ABBE_GH_TABLE_MAX_BYTES);
        (void)put_text(w, end, " bytes");
        *why = gh->stage.why;
        return ABBE_E_ARG;
    }
    gh->stage.slot = gh->running == 0u ? 1u : 0u;
    gh->stage.size = size;
    gh->stage.crc = crc;
    gh->stage.received = 0u;
    gh->stage.open = 1u;
    return ABBE_OK;
}

abbe_status_t abbe_gh_upload_data(abbe_gh_t *gh, uint32_t offset, const uint8_t *data, uint32_t n,
                                  const char **why)
{
    static const char *const none = "";
    *why = none;
    if (!gh->stage.open) {
        *why = "no upload open (begin with B,<size>,<crc32>)";
        return ABBE_E_ARG;
    }
    if (offset != gh->stage.received) {
        *why = "chunk out of order (offset is not the number of bytes received)";
        return ABBE_E_ARG;
    }
    /* the second test never binds (received <= size <= the slot's bytes): the
     * slot's bound stated where the copy is, for the proof (docs/proofs.md) */
    if (n > gh->stage.size - gh->stage.received || offset > ABBE_GH_TABLE_MAX_BYTES - n) {
        *why = "chunk runs past the announced size";
        return ABBE_E_ARG;
    }
    if (n != 0u) { /* an empty chunk at the end would pass memcpy a pointer past the slot */
        memcpy((uint8_t *)gh->slot[gh->stage.slot].blob + offset, data, n);
    }
    gh->stage.received += n;
    return ABBE_OK;
}

abbe_status_t abbe_gh_upload_commit(abbe_gh_t *gh, const char **why)
{
    static const char *const none = "";
    *why = none;
    if (!gh->stage.open) {
        *why = "no upload open (begin with B,<size>,<crc32>)";
        return ABBE_E_ARG;
    }
    gh->stage.open = 0u;
    abbe_gh_slot_t *s = &gh->slot[gh->stage.slot];
    if (gh->stage.received != gh->stage.size) {
        *why = "incomplete: fewer bytes received than announced";
        return ABBE_E_ARG;
    }
    if (abbe_crc32(0u, s->blob, gh->stage.size) != gh->stage.crc) {
        *why = "CRC-32 of the received bytes differs from the announced one";
        return ABBE_E_CRC;
    }
    /* Validate into the slot's model (on failure it is left untouched), derive
     * the segment length, then queue it: the compensator swaps at the start of
     * the next segment. The slot is not the running one; its model may be the
     * one that ran before, which nothing references any more. */
    abbe_status_t st = abbe_thermal_load(&s->model, &s->thermal, s->blob, gh->stage.size);
    if (st == ABBE_OK) {
        st = abbe_gh_slot_prepare(s);
    }
    if (st == ABBE_OK) {
        st = abbe_comp_swap_model(&gh->comp, &s->model);
    }
    if (st != ABBE_OK) {
        s->loaded = 0u;
        *why = abbe_strerror(st);
        return st;
    }
    gh->pending = gh->stage.slot;
    abbe_gh_update_seg_len(gh);
    return ABBE_OK;
}

void abbe_gh_upload_abort(abbe_gh_t *gh)
{
    gh->stage.open = 0u;
}

/* Eva harness: the grblHAL plugin's byte intake (port/grblhal, portable
 * core): a stored-table header of 16 unknown bytes with an unknown storage
 * capacity, and an upload session of unknown size and CRC whose chunks have
 * unknown offsets, lengths up to PROOF_CHUNK and contents (docs/proofs.md).
 * The commit's validation is the loader, proven by load3.c. */
#include "__fc_builtin.h"
#include "abbe_grblhal_core.h"

#ifndef PROOF_CHUNK
#define PROOF_CHUNK 64
#endif

static abbe_gh_t gh;
static uint8_t chunk[PROOF_CHUNK];

int main(void)
{
    const char *why;
    uint8_t header[ABBE_GH_STORE_HEADER_BYTES];
    Frama_C_make_unknown((char *)header, sizeof header);
    uint32_t size = 0, crc = 0;
    abbe_gh_store_t stored =
        abbe_gh_store_parse(header, Frama_C_unsigned_int_interval(0u, 0xFFFFFFFFu), &size, &crc, &why);
    abbe_gh_params_t params;
    abbe_gh_default_params(&params);
    if (abbe_gh_init(&gh, &params, NULL, 0u) != ABBE_OK) {
        return 1;
    }
    (void)abbe_gh_upload_begin(&gh, Frama_C_unsigned_int_interval(0u, 0xFFFFFFFFu),
                               Frama_C_unsigned_int_interval(0u, 0xFFFFFFFFu), &why);
    /* any number of chunks: the loop's body is every chunk */
    while (Frama_C_nondet(0, 1)) {
        Frama_C_make_unknown((char *)chunk, sizeof chunk);
        uint32_t n = Frama_C_unsigned_int_interval(0u, PROOF_CHUNK);
        //@ split n;
        (void)abbe_gh_upload_data(&gh, Frama_C_unsigned_int_interval(0u, 0xFFFFFFFFu), chunk, n, &why);
        //@ merge n;
    }
    if (Frama_C_nondet(0, 1)) {
        abbe_gh_upload_abort(&gh);
    }
    return (int)stored;
}

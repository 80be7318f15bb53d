/* Eva harness: the CAN node's configuration parser (port/socketcan, abbe_can_config_parse in
 * can_config_parse.c with the TOML numbers of can_toml_number.c, then
 * abbe_can_config_check) on every text of unknown bytes of every length
 * 0..PROOF_MAX_SIZE. strlen/strcmp/memcpy are Eva's built-ins; strncpy, strtod
 * and snprintf are Frama-C's libc contracts. */
#include "__fc_builtin.h"

#include "abbe_can_config.h"

#ifndef PROOF_MAX_SIZE
#define PROOF_MAX_SIZE 64
#endif

static char text[PROOF_MAX_SIZE];

int main(void)
{
    Frama_C_make_unknown(text, PROOF_MAX_SIZE);
    size_t len = Frama_C_interval(0, PROOF_MAX_SIZE);
    abbe_can_config_t cfg;
    abbe_can_config_error_t err;
    return abbe_can_config_parse(&cfg, text, len, "node.conf", &err);
}

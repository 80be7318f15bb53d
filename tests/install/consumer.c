/* Links against an installed abbe and checks a value the library computes. */
#include <stdio.h>

#include "abbe/abbe.h"

int main(void)
{
    static const char check[] = "123456789";
    uint32_t crc = abbe_crc32(0u, check, sizeof check - 1u);
    abbe_model_t model;
    int status = abbe_model_load(&model, check, sizeof check - 1u);
    printf("abbe %s: crc32(\"123456789\") = 0x%08x, load(garbage) = %d (%s)\n",
           ABBE_VERSION_STRING, (unsigned)crc, status, abbe_strerror(status));
    return (crc == 0xCBF43926u && status == ABBE_E_TRUNCATED) ? 0 : 1;
}

/* abbe: status strings. */
#include "abbe/status.h"

const char *abbe_strerror(int status)
{
    switch (status) {
    case ABBE_OK: return "ok";
    case ABBE_E_ARG: return "invalid argument";
    case ABBE_E_TRUNCATED: return "table truncated";
    case ABBE_E_MAGIC: return "bad magic: not an abbe table";
    case ABBE_E_VERSION_MAJOR: return "unsupported table major version";
    case ABBE_E_VERSION_MINOR: return "table minor version too new";
    case ABBE_E_SIZE: return "inconsistent table sizes";
    case ABBE_E_CRC: return "table CRC-32 mismatch";
    case ABBE_E_FLAGS: return "unknown feature or reserved field set";
    case ABBE_E_COUNT: return "count over its cap";
    case ABBE_E_OFFSET: return "coefficient array out of bounds";
    case ABBE_E_NONFINITE: return "NaN or infinite coefficient";
    case ABBE_E_PERIOD: return "bad Fourier period";
    case ABBE_E_TRAVEL: return "travel min not below max";
    case ABBE_E_RANGE: return "table value out of range";
    case ABBE_E_INPUT: return "NaN or infinite input";
    case ABBE_E_NO_MODEL: return "no model loaded";
    case ABBE_E_MISMATCH: return "float32 twin differs from int32";
    case ABBE_E_ALIGN: return "table not 4-byte aligned";
    case ABBE_E_KIND: return "five-axis kind not built into this library";
    default: return "unknown status";
    }
}

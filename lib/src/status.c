/* abbe: status strings. */
#include "abbe/status.h"

const char *abbe_strerror(int status)
{
    switch (status) {
    case ABBE_OK: return "ok";
    case ABBE_E_ARG: return "invalid argument";
    case ABBE_E_TRUNCATED: return "table truncated: shorter than its header or declared size";
    case ABBE_E_MAGIC: return "not an abbe table (bad magic)";
    case ABBE_E_VERSION_MAJOR: return "table format major version not supported";
    case ABBE_E_VERSION_MINOR: return "table format minor version newer than this library";
    case ABBE_E_SIZE: return "table header sizes inconsistent";
    case ABBE_E_CRC: return "table CRC-32 mismatch";
    case ABBE_E_FLAGS: return "unknown feature bit or non-zero reserved/disabled field";
    case ABBE_E_COUNT: return "table count over its cap";
    case ABBE_E_OFFSET: return "coefficient array out of bounds or misaligned";
    case ABBE_E_NONFINITE: return "NaN or infinite coefficient";
    case ABBE_E_PERIOD: return "Fourier period not positive, or unused block fields set";
    case ABBE_E_TRAVEL: return "travel minimum not below maximum";
    case ABBE_E_RANGE: return "table value outside its representable range";
    case ABBE_E_INPUT: return "NaN or infinite input";
    case ABBE_E_NO_MODEL: return "no model loaded";
    case ABBE_E_MISMATCH: return "float32 coefficient differs from its int32 value";
    case ABBE_E_ALIGN: return "table not 4-byte aligned";
    default: return "unknown status";
    }
}

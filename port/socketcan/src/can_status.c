/* abbe CAN port: status strings. */
#include "abbe_can.h"

const char *abbe_can_strerror(int status)
{
    switch (status) {
    case ABBE_CAN_OK: return "ok";
    case ABBE_CAN_E_ARG: return "invalid argument";
    case ABBE_CAN_E_CONFIG: return "invalid configuration";
    case ABBE_CAN_E_AGAIN: return "would block";
    case ABBE_CAN_E_CLOSED: return "peer closed the connection";
    case ABBE_CAN_E_IO: return "I/O error";
    case ABBE_CAN_E_BUSY: return "a model is already queued for the next cycle";
    case ABBE_CAN_E_TOO_BIG: return "model file too large";
    case ABBE_CAN_E_UNSUPPORTED: return "not supported here";
    case ABBE_CAN_E_FRAME: return "record is not one CAN frame";
    case ABBE_CAN_E_PARSE: return "not a candump -l log line";
    default: return abbe_strerror(status);
    }
}

const char *abbe_can_status_name(int status)
{
    switch (status) {
    case ABBE_CAN_OK: return "ABBE_OK";
    case ABBE_CAN_E_ARG: return "ABBE_CAN_E_ARG";
    case ABBE_CAN_E_CONFIG: return "ABBE_CAN_E_CONFIG";
    case ABBE_CAN_E_AGAIN: return "ABBE_CAN_E_AGAIN";
    case ABBE_CAN_E_CLOSED: return "ABBE_CAN_E_CLOSED";
    case ABBE_CAN_E_IO: return "ABBE_CAN_E_IO";
    case ABBE_CAN_E_BUSY: return "ABBE_CAN_E_BUSY";
    case ABBE_CAN_E_TOO_BIG: return "ABBE_CAN_E_TOO_BIG";
    case ABBE_CAN_E_UNSUPPORTED: return "ABBE_CAN_E_UNSUPPORTED";
    case ABBE_CAN_E_FRAME: return "ABBE_CAN_E_FRAME";
    case ABBE_CAN_E_PARSE: return "ABBE_CAN_E_PARSE";
    case ABBE_E_ARG: return "ABBE_E_ARG";
    case ABBE_E_TRUNCATED: return "ABBE_E_TRUNCATED";
    case ABBE_E_MAGIC: return "ABBE_E_MAGIC";
    case ABBE_E_VERSION_MAJOR: return "ABBE_E_VERSION_MAJOR";
    case ABBE_E_VERSION_MINOR: return "ABBE_E_VERSION_MINOR";
    case ABBE_E_SIZE: return "ABBE_E_SIZE";
    case ABBE_E_CRC: return "ABBE_E_CRC";
    case ABBE_E_FLAGS: return "ABBE_E_FLAGS";
    case ABBE_E_COUNT: return "ABBE_E_COUNT";
    case ABBE_E_OFFSET: return "ABBE_E_OFFSET";
    case ABBE_E_NONFINITE: return "ABBE_E_NONFINITE";
    case ABBE_E_PERIOD: return "ABBE_E_PERIOD";
    case ABBE_E_TRAVEL: return "ABBE_E_TRAVEL";
    case ABBE_E_RANGE: return "ABBE_E_RANGE";
    case ABBE_E_INPUT: return "ABBE_E_INPUT";
    case ABBE_E_NO_MODEL: return "ABBE_E_NO_MODEL";
    case ABBE_E_MISMATCH: return "ABBE_E_MISMATCH";
    case ABBE_E_ALIGN: return "ABBE_E_ALIGN";
    case ABBE_E_KIND: return "ABBE_E_KIND";
    default: return "unknown status";
    }
}

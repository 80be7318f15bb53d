/* abbe: status codes. 0 is success, every failure is a distinct negative code. */
#ifndef ABBE_STATUS_H
#define ABBE_STATUS_H

/* C linkage for C++ callers (firmware in C++ links the C library). */
#ifdef __cplusplus
extern "C" {
#endif

typedef enum {
    ABBE_OK = 0,
    ABBE_E_ARG = -1,            /* NULL pointer or argument outside its documented range */
    ABBE_E_TRUNCATED = -2,      /* blob shorter than its header or its declared total_size */
    ABBE_E_MAGIC = -3,          /* not an abbe table */
    ABBE_E_VERSION_MAJOR = -4,  /* table format major version not supported */
    ABBE_E_VERSION_MINOR = -5,  /* table format minor version newer than this library */
    ABBE_E_SIZE = -6,           /* header_size, axis_record_size or total_size inconsistent */
    ABBE_E_CRC = -7,            /* CRC-32 mismatch: table damaged */
    ABBE_E_FLAGS = -8,          /* unknown feature bit, non-zero reserved field, field of a disabled feature */
    ABBE_E_COUNT = -9,          /* a count over its cap (degree, harmonics, term mask, coefficient count) */
    ABBE_E_OFFSET = -10,        /* coefficient array out of bounds or misaligned */
    ABBE_E_NONFINITE = -11,     /* NaN or infinity in a float field */
    ABBE_E_PERIOD = -12,        /* Fourier period <= 0, or fields set for an unused block */
    ABBE_E_TRAVEL = -13,        /* travel_min >= travel_max */
    ABBE_E_RANGE = -14,         /* a value outside the range that keeps fixed point exact */
    ABBE_E_INPUT = -15,         /* NaN or infinite input (float path) */
    ABBE_E_NO_MODEL = -16,      /* compensator has no model loaded */
    ABBE_E_MISMATCH = -17,      /* a float32 coefficient is not its int32 twin converted */
    ABBE_E_ALIGN = -18,         /* blob not 4-byte aligned (coefficients are read in place) */
    ABBE_E_KIND = -19           /* a five-axis kinematics kind this library was built without (ABBE_FIVE_KINDS) */
} abbe_status_t;

/* The most negative status: every status lies in [ABBE_STATUS_MIN, ABBE_OK].
 * Move it with the enum when a status is added. */
#define ABBE_STATUS_MIN ABBE_E_KIND

/* Human-readable, static, never NULL (unknown codes give "unknown status"). */
const char *abbe_strerror(int status);

#ifdef __cplusplus
} /* extern "C" */
#endif

#endif /* ABBE_STATUS_H */

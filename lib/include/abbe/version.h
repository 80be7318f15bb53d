/* abbe: library and table-format versions. */
#ifndef ABBE_VERSION_H
#define ABBE_VERSION_H

#define ABBE_VERSION_MAJOR 0
#define ABBE_VERSION_MINOR 1
#define ABBE_VERSION_PATCH 0
#define ABBE_VERSION_STRING "0.1.0"

/* Table format the library reads (docs/table-format.md). Blobs with another
 * major, or a newer minor, are refused; older minors (1.0) are read. A library
 * built without the reversal blocks of format 1.1 (CMake option
 * ABBE_WITH_REVERSAL=OFF, which defines ABBE_NO_REVERSAL for the library and
 * everything that links it) reads format 1.0 only, with the flash and run
 * time of the 1.0 library. */
#define ABBE_TABLE_FORMAT_MAJOR 1
#if defined(ABBE_NO_REVERSAL)
#define ABBE_TABLE_FORMAT_MINOR 0
#else
#define ABBE_TABLE_FORMAT_MINOR 1
#endif

#endif /* ABBE_VERSION_H */

/* abbe: library and table-format versions. */
#ifndef ABBE_VERSION_H
#define ABBE_VERSION_H

#define ABBE_VERSION_MAJOR 0
#define ABBE_VERSION_MINOR 1
#define ABBE_VERSION_PATCH 0
#define ABBE_VERSION_STRING "0.1.0"

/* Table format the library reads (docs/table-format.md). Blobs with another
 * major, or a newer minor, are refused. */
#define ABBE_TABLE_FORMAT_MAJOR 1
#define ABBE_TABLE_FORMAT_MINOR 0

#endif /* ABBE_VERSION_H */

/* Writes every golden table blob to OUTDIR/<index>-<name>.bin: the fuzzer's
 * seed corpus.  Usage: make_corpus OUTDIR */
#include <stdio.h>
#include <string.h>

#include "golden_data.h"
#include "golden_five.h"
#include "golden_thermal.h"

int main(int argc, char **argv)
{
    if (argc != 2) {
        fprintf(stderr, "usage: %s OUTDIR\n", argv[0]);
        return 2;
    }
    unsigned written = 0;
    for (unsigned i = 0; i < abbe_golden_table_count; i++) {
        const abbe_golden_table_t *t = &abbe_golden_tables[i];
        char path[4096];
        snprintf(path, sizeof path, "%s/%02u-%s.bin", argv[1], i, t->name);
        FILE *f = fopen(path, "wb");
        if (f == NULL || fwrite(t->blob, 1, t->blob_size, f) != t->blob_size || fclose(f) != 0) {
            fprintf(stderr, "make_corpus: cannot write %s\n", path);
            return 1;
        }
        written++;
    }
    for (unsigned i = 0; i < abbe_golden_five_table_count; i++) { /* format 1.2 (fuzz_five_load) */
        const abbe_golden_five_table_t *t = &abbe_golden_five_tables[i];
        char path[4096];
        snprintf(path, sizeof path, "%s/five-%02u-%s.bin", argv[1], i, t->name);
        FILE *f = fopen(path, "wb");
        if (f == NULL || fwrite(t->blob, 1, t->blob_size, f) != t->blob_size || fclose(f) != 0) {
            fprintf(stderr, "make_corpus: cannot write %s\n", path);
            return 1;
        }
        written++;
    }
    { /* format 1.3: the thermal golden table (fuzz_thermal_load) */
        char path[4096];
        snprintf(path, sizeof path, "%s/thermal-golden.bin", argv[1]);
        FILE *f = fopen(path, "wb");
        if (f == NULL || fwrite(abbe_golden_thermal_blob, 1, abbe_golden_thermal_blob_size, f) !=
                             abbe_golden_thermal_blob_size || fclose(f) != 0) {
            fprintf(stderr, "make_corpus: cannot write %s\n", path);
            return 1;
        }
        written++;
    }
    printf("make_corpus: %u seeds in %s\n", written, argv[1]);
    return written ? 0 : 1;
}

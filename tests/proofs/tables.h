/* The golden tables an evaluator harness runs on (eval_q.c, eval_f32.c,
 * eval_five_q.c, eval_five_f32.c): scripts/prove.sh writes PROOF_TABLES_H,
 * which defines each table's bytes as table_<name>[] and lists them as
 * PROOF_TABLES, one X(name) each. The harness copies one of them (any,
 * proof_which) into blob. */
#ifndef PROOF_TABLES_INCLUDED
#define PROOF_TABLES_INCLUDED

#include <stddef.h>
#include <stdint.h>

#define PROOF_STR2(x) #x
#define PROOF_STR(x) PROOF_STR2(x)
#include PROOF_STR(PROOF_TABLES_H)

#define X(t) {table_##t, sizeof table_##t},
static const struct {
    const unsigned char *bytes;
    size_t size;
} proof_tables[] = {PROOF_TABLES};
#undef X
#define PROOF_N_TABLES ((unsigned)(sizeof proof_tables / sizeof proof_tables[0]))

/* the table analysed. scripts/prove.sh gives each harness one table: with
 * several, Eva (-eva-partition-value on this variable or a split in main)
 * still joined the tables' models in places (measured: 4 alarms in the
 * kernels' coefficient reads), so one analysis per table it is */
static unsigned proof_which;

/* room for the largest golden table (full: 6,020 B); the memcpy's
 * precondition checks each fits */
#define PROOF_BLOB_BYTES 8192u
static uint32_t blob[PROOF_BLOB_BYTES / 4u];

#endif /* PROOF_TABLES_INCLUDED */

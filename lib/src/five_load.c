/* abbe: the five-axis loader, abbe_five_model_load() (format 1.2, abbe/five_axis.h).
 *
 * model_load.c compiled a second time with ABBE_MODEL_LOAD_FIVE: the checks of
 * the header and the linear axes are the same source, inlined here for a table
 * that may carry the rotary section, and model_load.c's own translation unit
 * (the 3-axis loader) stays exactly what it was: a 3-axis firmware pays no
 * flash for five-axis tables (bench/results.md). A library without format
 * 1.1 (ABBE_NO_REVERSAL) reads no five-axis tables. */
#if !defined(ABBE_NO_REVERSAL)
#define ABBE_MODEL_LOAD_FIVE 1
#include "model_load.c" /* NOLINT(bugprone-suspicious-include): the same source compiled twice, on purpose */
#else
typedef int abbe_five_load_not_built; /* ISO C: a translation unit is not empty */
#endif

"""Resource bounds of every reader, in one place (docs/formats.md, "Limits").

A file beyond a bound is refused with an AbbeInputError naming the file (and the
line, where there is one) before the work it would cause is started, so memory
and time stay linear in an input of bounded size. Sizes in bytes, lengths in
characters.
"""

from __future__ import annotations

KIB, MIB = 1 << 10, 1 << 20

#: Longest line of any text file (characters, without the newline).
MAX_LINE_CHARS = 65_536
#: Deepest nesting of arrays / tables / objects in TOML and JSON files.
MAX_NESTING = 32

MACHINE_FILE_MAX_BYTES = 1 * MIB
SPEC_FILE_MAX_BYTES = 1 * MIB

#: 6D laser CSV: a continuous capture of 10^6 readings is about 100 MiB.
LASER_CSV_MAX_BYTES = 256 * MIB
LASER_CSV_MAX_ROWS = 2_000_000
LASER_MAX_RUNS = 100

BALLBAR_CSV_MAX_BYTES = 64 * MIB
#: Five-axis probing / R-test / indexer CSV files.
FIVE_AXIS_CSV_MAX_BYTES = 64 * MIB
FIVE_AXIS_CSV_MAX_ROWS = 1_000_000
BALLBAR_CSV_MAX_ROWS = 1_000_000

DAT_MAX_BYTES = 64 * MIB
DAT_MAX_POSITIONS = 100_000
DAT_MAX_CYCLES = 100

#: A table blob is at most a few KiB (docs/table-format.md); anything larger is not one.
BLOB_MAX_BYTES = 64 * KIB
#: Table JSON (``model.json`` of ``abbe fit`` included, with its targets and metrics).
TABLE_JSON_MAX_BYTES = 16 * MIB
TRUTH_JSON_MAX_BYTES = 64 * MIB

#: ``abbe fit`` fits lines with more targets on this many bins of consecutive targets
#: (the mean of each bin), so its time and memory do not grow with a dense capture.
FIT_MAX_TARGETS = 256

#: ISO 230-1 error files of ``abbe import``: a TF5280 ISG CSV file or an Etalon exchange
#: file (a controller reads a few thousand records: ``vol_comp[i].max_records``).
COMPONENT_FILE_MAX_BYTES = 16 * MIB
COMPONENT_FILE_MAX_RECORDS = 100_000
#: A TF5280 compensation list (``.lis``): a few dozen lines naming up to 10 files.
LIS_MAX_BYTES = 64 * KIB
LIS_MAX_FILES = 10
#: ``abbe import --max-points``: positions per axis fitted (the fit's own bound).
IMPORT_MAX_POINTS = FIT_MAX_TARGETS

#: Renishaw laser ``.rtl`` export: a target list and run/target/value rows.
RTL_MAX_BYTES = 64 * MIB
RTL_MAX_TARGETS = 100_000
#: Passes ("runs" of the file): two per bidirectional cycle, at most LASER_MAX_RUNS cycles.
RTL_MAX_PASSES = 2 * LASER_MAX_RUNS
#: Renishaw ballbar ``.b5r`` (XML): a few thousand samples per run.
B5R_MAX_BYTES = 64 * MIB
B5R_MAX_SAMPLES = 1_000_000

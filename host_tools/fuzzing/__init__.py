"""The project's own fuzzers of the Python readers and commands (docs/formats.md, "Promises").

* :mod:`fuzzing.seeds`: a small valid workspace (machine file, laser CSV, ballbar CSV,
  ESS .dat, table blob and JSON, simulation spec) and every command's argument lines;
* :mod:`fuzzing.mutate`: mutation operators (bytes, lines, cells, encodings, hostile
  numbers and tokens);
* :mod:`fuzzing.harness`: runs one command on one input and checks the promises: exit 0
  or 2 (3 without the C library), never a traceback or 70, a one-line message naming
  the file, nothing written or changed on failure, no staging leftovers, strict JSON
  out, and a time bound;
* ``python -m fuzzing.run`` (from host_tools/): the long run, seeded, for minutes or
  hours, in a memory-limited subprocess.

tests/cli/test_fuzz_commands.py and tests/formats/test_fuzz_readers.py run them
seeded and bounded in CI.
"""

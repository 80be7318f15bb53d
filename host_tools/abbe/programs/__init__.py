"""Measurement part programs: the tests of a machine file as controller-neutral steps
(:mod:`.plan`) and as each controller's program text (:mod:`.dialects`); docs/programs.md."""

"""A second independent generator of diagnose cases (issue 36), for evaluation only.

Written from docs/concepts.md, docs/formats.md, docs/table-format.md and
docs/effects.md only -- not from ``abbe.sim``, ``cases.hidden_effects`` or
``cases.independent`` (a test checks it imports none of them). Its machine is a
set of ISO 230-1 error motions composed by exact homogeneous transforms
(``machine``); its drives, effects and instruments (``instruments``) are its own
(first-order loops at 1 kHz, a play operator, time-sampled ballbar with AR(1)
noise and 0.1 um resolution, wrapped angles in half the files); its model is
fitted by ``abbe fit`` from simulated commissioning laser lines, so it carries a
real fit error. ``suite`` builds the cases (single effects, pairs, clean
machines, effects near the detection limit) and scores a diagnosis.
"""

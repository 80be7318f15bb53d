"""An independent generator of diagnose cases, for evaluation only.

Written from the physics in docs/effects.md and /work/shared/reference/notes.md
(§1 kinematic chain, §3 ISO 230-2, §4 ballbar signatures), **not** from the code
of ``abbe.sim`` or ``cases.hidden_effects``: it imports neither, has its own
kinematic chain (4x4 homogeneous transforms), its own error shapes (Legendre
polynomials and free sines instead of the library basis), its own effect shapes
(lost motion as a play with a linear, exponential or smooth take-up, possibly
different per reversal direction; servo lag as a pure delay or a first-order
lag; drift linear or exponential in time with the expansion about the screw's
fixed bearing; scale as ppm or as a bow; a straightness bow as a sine arch;
tool offsets seen by circles at several Z heights) and its own instruments
(time-sampled ballbar, ISO 230-2 laser cycles with uneven targets, ESS ``.dat``
positioning files with start-up outliers). It writes the documented files
(docs/formats.md: machine TOML, 6D laser CSV, ballbar CSV, ``.dat``) and the
model (a table blob, the user's "current model"), so the diagnosis is run
exactly as a user would run it, through the readers.

Its only uses of ``abbe`` are the product's public data types for the *model*
(``abbe.model.table.Table`` and ``abbe.formats.blob.write_blob``) and, in the
suite, the entry points ``diagnose_machine`` / ``diagnose_positioning``.

Selection thresholds of ``abbe diagnose`` are never tuned on these cases: they
are tuned on ``cases.hidden_effects``; this suite only measures.

Modules: :mod:`.physics` (machine and effects), :mod:`.chain` (kinematics),
:mod:`.measure` (instruments), :mod:`.files` (writers), :mod:`.suite` (cases,
expected answers, scoring).
"""

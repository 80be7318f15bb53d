"""Thermal identification and evaluation (docs/thermal.md).

* :mod:`.identify`: per displacement channel, forward selection of lagged inputs
  (temperatures, spindle speed) with a collinearity guard, scored by leave-one-cycle-out
  cross-validation inside the identification hours; time constants and gains refined by
  nonlinear least squares (scipy), 95 % intervals from the Jacobian; the model written in
  :mod:`abbe.model.thermal`'s form (what the C runtime runs).
* :mod:`.iso230_3`: the ISO 230-3 evaluation of a record: drift of every channel, tilts from
  sensor pairs, the envelope.
* :mod:`.report`: the HTML report (plots first, numbers after).
"""

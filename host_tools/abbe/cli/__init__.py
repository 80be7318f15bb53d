"""The ``abbe`` command line (see :mod:`abbe.cli.entry`)."""

import os

# One BLAS thread unless the user sets OPENBLAS_NUM_THREADS (it must be set before numpy
# loads, hence here, before the commands import it). abbe's matrices are small (hundreds
# of rows by tens of columns), where OpenBLAS's threads cost more than they give, and on
# a machine whose cores are busy far more: measured on the 2-core test machine under
# load, an SVD of 324 x 52 took 165 ms with OpenBLAS's threads and 1.5 ms with one, and
# an R-test-only five-axis fit of 108 rows with harmonics 2 spent 7.7 of its 11.5 s in
# such SVDs (issue 34, item 6).
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

from abbe.cli.entry import main  # noqa: E402

__all__ = ["main"]

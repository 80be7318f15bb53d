"""``python -m abbe.cli``: the ``abbe`` command."""

import sys

from abbe.cli.entry import main

sys.exit(main())

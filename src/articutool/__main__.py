"""``python -m articutool``: the ``articutool`` command."""

import sys

from articutool.cli import main

sys.exit(main())

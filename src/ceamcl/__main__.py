"""``python -m ceamcl``: the same as the ``ceamcl`` command."""

import sys

from ceamcl.cli import main

sys.exit(main())

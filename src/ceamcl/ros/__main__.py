"""``python -m ceamcl.ros [--params FILE] [--autostart] [--ros-args ...]``: the node."""

import sys

from ceamcl.cli import main

sys.exit(main(["node", *sys.argv[1:]]))

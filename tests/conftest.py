"""The whole suite: ``make test`` runs it on two pytest-xdist workers (``-n 2``).

An xdist worker is started with ``COLUMNS=80`` and ``LINES=24`` in its environment (execnet
sets them for its child processes), which the command line reads as the user's terminal
width (:func:`ceamcl.cli.main`). The suite removes them in a worker, so a test sees
the environment of a serial run (no width set: tables of 100 columns, as a pipe gets).
"""

from __future__ import annotations

import os

if os.environ.get("PYTEST_XDIST_WORKER"):
    for name in ("COLUMNS", "LINES"):
        os.environ.pop(name, None)

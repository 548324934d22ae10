"""Output folders this process created, so a failed or interrupted run can remove them.

:func:`ceamcl.io.results.ensure_output_dir` notes the outermost folder it had to create;
:func:`remove_created` deletes exactly those (with what was written into them) and nothing
that existed before the run. The CLI calls it when a command fails or is interrupted.
"""

from __future__ import annotations

import shutil
from pathlib import Path

__all__ = ["forget", "missing_ancestor", "note_created", "remove_created"]

_created: list[Path] = []


def missing_ancestor(path: Path) -> Path | None:
    """The outermost folder of ``path`` (itself included) that does not exist yet, if any."""
    top = None
    for folder in (path, *path.parents):
        if folder.exists():
            break
        top = folder
    return top


def note_created(folder: Path) -> None:
    _created.append(folder.resolve())


def forget() -> None:
    """Keep what was created (the command succeeded)."""
    _created.clear()


def remove_created() -> list[Path]:
    """Delete the folders noted since the last :func:`forget`; return those removed."""
    removed = []
    while _created:
        folder = _created.pop()
        if folder.is_dir():
            shutil.rmtree(folder, ignore_errors=True)
            removed.append(folder)
    return removed

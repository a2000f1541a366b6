"""Whether the file system can name a path (:func:`too_long`): the command line refuses one it
cannot as a wrong argument (exit status 2) before anything is opened."""

from __future__ import annotations

import os
from pathlib import Path


def _is_dir(path: Path) -> bool:
    """``path.is_dir()``, False where the path itself is too long to look up."""
    try:
        return path.is_dir()
    except OSError:
        return False


def too_long(path: Path, room: int = 0) -> str | None:
    """Why the file system would refuse ``path`` with ENAMETOOLONG (a name in it longer than
    ``NAME_MAX``, or, as an absolute path with ``room`` bytes more, longer than ``PATH_MAX``),
    or None. The limits are those of the nearest folder of ``path`` that exists (255 and
    4096 bytes where it cannot say): each command then refuses it as a wrong argument, where
    opening it raised OSError, a traceback, exit 1."""
    absolute = Path(os.path.abspath(path))
    existing = next((p for p in (absolute, *absolute.parents) if _is_dir(p)), Path("/"))
    try:
        name_max = os.pathconf(existing, "PC_NAME_MAX")
        path_max = os.pathconf(existing, "PC_PATH_MAX")
    except (OSError, ValueError):
        name_max, path_max = 255, 4096
    for name in path.parts:
        size = len(os.fsencode(name))
        if size > name_max:
            shown = name if len(name) <= 24 else f"{name[:12]}...{name[-8:]}"
            return (
                f"the name {shown!r} in the path is {size} bytes long, longer than the "
                f"{name_max} bytes a file name may have"
            )
    size = len(os.fsencode(str(absolute)))
    if size + room >= path_max:
        inside = f", less {room} for the files written inside it" if room else ""
        return (
            f"the path is {size} bytes long as an absolute path, longer than the "
            f"{path_max - 1 - room} bytes allowed (PATH_MAX {path_max}{inside})"
        )
    return None

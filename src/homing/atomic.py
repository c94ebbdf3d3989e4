"""Atomic file writes: a reader sees the old file or the new one, never half of one.

Maps, pictures, benchmark JSON and run-log indexes are written through
:func:`atomic_write`: the bytes go to a temporary file in the same directory,
are flushed to disk, and the temporary file is renamed over the target
(``os.replace`` is atomic on POSIX within one file system).

The temporary file is private while it is written (``mkstemp`` makes it
0600); before the rename it gets the mode a plain ``open(path, "w")`` would
have given: the mode of the file it replaces, or ``0666`` less the umask for
a new one — so a saved map is as readable as any other file the user makes.
"""

from __future__ import annotations

import os
import stat
import tempfile
from pathlib import Path

NEW_FILE_MODE = 0o666  # before the umask, as open(2) with O_CREAT


def current_umask() -> int:
    """The process's umask (read by setting it and putting it back)."""
    mask = os.umask(0o022)
    os.umask(mask)
    return mask


def new_file_mode(target: Path) -> int:
    """The permission bits ``target`` gets: those of the file it replaces, else 0666 less the umask."""
    try:
        st = target.stat()
    except OSError:
        return NEW_FILE_MODE & ~current_umask()
    return stat.S_IMODE(st.st_mode) if stat.S_ISREG(st.st_mode) else NEW_FILE_MODE & ~current_umask()


def atomic_write(path: str | Path, data: bytes | str) -> Path:
    """Write ``data`` to ``path`` atomically and return the path.

    Creates missing parent directories. ``str`` data is encoded as UTF-8.
    """
    target = Path(path)
    target.parent.mkdir(parents=True, exist_ok=True)
    payload = data.encode("utf-8") if isinstance(data, str) else data
    mode = new_file_mode(target)
    fd, tmp = tempfile.mkstemp(prefix=f".{target.name}.", suffix=".tmp", dir=target.parent)
    try:
        with os.fdopen(fd, "wb") as f:
            f.write(payload)
            f.flush()
            os.fchmod(f.fileno(), mode)
            os.fsync(f.fileno())
        os.replace(tmp, target)
    except BaseException:
        try:
            os.unlink(tmp)
        except FileNotFoundError:
            pass
        raise
    return target

"""Output paths checked before a long run starts, so a typo costs a second, not an hour.

Every command that writes a file (``--out``, ``--save-map``, ``--log``,
``--json``, ``--record``, ``schema -o``…) calls :func:`check_output` on it
while parsing its arguments: the path must not be a folder, a file already
there must be writable, and the folder it goes in must exist or be makeable
and accept a new file. The check writes nothing but a probe file it removes
at once (so it also catches what permission bits do not show: a read-only
file system, or a pseudo-file system such as ``/sys``); it creates no folder.
"""

from __future__ import annotations

import os
import tempfile
from pathlib import Path

from homing.errors import UserError


def _nearest_existing(folder: Path) -> Path:
    while not folder.exists() and folder != folder.parent:
        folder = folder.parent
    return folder


def check_output(path: str | Path, option: str) -> Path:
    """``path`` as a :class:`~pathlib.Path` if a file can be written there; else :class:`UserError` naming ``option``.

    ``option`` is how the user gave the path (``"--save-map"``, ``"-o"``), for the message.
    """
    text = str(path)
    if not text.strip():
        raise UserError(f"{option}: needs a file path, not an empty string")
    try:
        target = Path(text).expanduser()
        if target.is_dir():
            raise UserError(f"{option} {text}: is a folder; give a file path")
        if target.exists() and not os.access(target, os.W_OK):
            raise UserError(f"{option} {text}: the file exists and is read-only")
        folder = target.parent
        base = _nearest_existing(folder)
        if not base.is_dir():
            raise UserError(f"{option} {text}: cannot make the folder {folder}: {base} is a file")
        try:
            fd, probe = tempfile.mkstemp(prefix=".homing-probe-", dir=base)
        except OSError as err:
            what = "write in" if base == folder else f"make the folder {folder} in"
            raise UserError(f"{option} {text}: cannot {what} {base}: {err.strerror}") from None
        os.close(fd)
        os.unlink(probe)
    except ValueError as err:  # e.g. an embedded NUL byte
        raise UserError(f"{option}: not a usable path ({err})") from None
    return target


def check_folder(path: str | Path, option: str) -> Path:
    """``path`` if it is a folder that accepts new files, or one that can be made; else :class:`UserError`."""
    target = Path(str(path)).expanduser()
    if target.exists() and not target.is_dir():
        raise UserError(f"{option} {path}: is a file; give a folder")
    check_output(target / ".homing-probe", option)
    return target


def map_files(path: str | Path) -> tuple[Path, Path]:
    """The two files a map_server map saved as ``path`` is made of: (``.yaml``, ``.pgm``), as ``save_map`` names them."""
    yaml_path = Path(path)
    if yaml_path.suffix != ".yaml":
        yaml_path = yaml_path.with_suffix(".yaml")
    return yaml_path, yaml_path.with_suffix(".pgm")

"""Import pybullet without its build banner.

pybullet's C module prints "pybullet build time: …" when first imported,
which would land between the lines of a user's plain-text run log or the
live view. Importing it once here, with file descriptors 1 and 2 pointed at
/dev/null, keeps the terminal clean; later ``import pybullet`` statements
reuse the loaded module and print nothing. Errors still surface as Python
exceptions.
"""

from __future__ import annotations

import ctypes
import os
import sys
from types import ModuleType


def import_pybullet() -> ModuleType:
    """Return the pybullet module, importing it silently the first time."""
    if "pybullet" in sys.modules:
        return sys.modules["pybullet"]
    sys.stdout.flush()
    sys.stderr.flush()
    saved = [os.dup(1), os.dup(2)]
    try:
        with open(os.devnull, "wb") as null:
            os.dup2(null.fileno(), 1)
            os.dup2(null.fileno(), 2)
            import pybullet

            # Whatever sits in C stdio's buffers goes to /dev/null, not to the restored fds.
            ctypes.CDLL(None).fflush(None)
    finally:
        os.dup2(saved[0], 1)
        os.dup2(saved[1], 2)
        os.close(saved[0])
        os.close(saved[1])
    return pybullet

"""A pseudo-terminal standing in for a USB-serial device, with optional line noise.

The emulator holds the master side; the adapter opens the slave side with
pyserial, by a stable symlink (``folder/kobuki`` → ``/dev/pts/N``), as it
would open ``/dev/kobuki`` on the robot. The slave is put in raw mode so the
line discipline passes every byte unchanged. :meth:`PtyLink.unplug` closes
the pty and removes the link, as pulling the USB cable does (the adapter's
reads fail); :meth:`PtyLink.replug` opens a new pty behind the same link.

Writes never block: bytes the other side has not read pile up in the
kernel's buffer and, once it is full, are dropped and counted, as a real
line drops what nobody reads. :class:`LineNoise` corrupts what is written:
bit flips, bursts of garbage, and writes cut short, all from a seeded
generator.
"""

from __future__ import annotations

import errno
import os
import tty
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np


@dataclass
class LineNoise:
    """Seeded line noise: per byte, a flipped bit with probability ``flip``; per write, a burst of
    1–8 random bytes inserted with probability ``garbage`` and the write cut short with probability ``cut``."""

    flip: float = 0.0
    garbage: float = 0.0
    cut: float = 0.0
    seed: int = 0
    rng: np.random.Generator = field(init=False)
    flipped: int = 0
    bursts: int = 0
    cuts: int = 0

    def __post_init__(self) -> None:
        self.rng = np.random.default_rng(self.seed)

    @property
    def active(self) -> bool:
        return self.flip > 0 or self.garbage > 0 or self.cut > 0

    def __call__(self, data: bytes) -> bytes:
        if not self.active or not data:
            return data
        buf = bytearray(data)
        if self.flip > 0:
            hits = np.nonzero(self.rng.random(len(buf)) < self.flip)[0]
            for i in hits.tolist():
                buf[i] ^= 1 << int(self.rng.integers(8))
            self.flipped += len(hits)
        if self.cut > 0 and self.rng.random() < self.cut:
            del buf[int(self.rng.integers(len(buf))):]
            self.cuts += 1
        if self.garbage > 0 and self.rng.random() < self.garbage:
            at = int(self.rng.integers(len(buf) + 1))
            buf[at:at] = self.rng.integers(0, 256, int(self.rng.integers(1, 9)), dtype=np.uint8).tobytes()
            self.bursts += 1
        return bytes(buf)


class PtyLink:
    """One emulated serial device: a pty behind a symlink at ``link``."""

    def __init__(self, link: str | Path, noise: LineNoise | None = None):
        self.link = Path(link)
        self.noise = noise or LineNoise()
        self.master: int | None = None
        self.slave: int | None = None
        self.written = 0  # bytes handed to the line
        self.dropped = 0  # bytes the line could not take (nobody reading)

    @property
    def plugged(self) -> bool:
        return self.master is not None

    def open(self) -> None:
        master, slave = os.openpty()
        tty.setraw(slave)
        os.set_blocking(master, False)
        self.master, self.slave = master, slave
        tmp = self.link.with_name(f".{self.link.name}.tmp")
        tmp.unlink(missing_ok=True)
        tmp.symlink_to(os.ttyname(slave))
        os.replace(tmp, self.link)

    def close(self) -> None:
        for fd in (self.master, self.slave):
            if fd is not None:
                os.close(fd)
        self.master = self.slave = None

    def unplug(self) -> None:
        """As pulling the cable: the link disappears and the adapter's reads fail."""
        self.link.unlink(missing_ok=True)
        self.close()

    def replug(self) -> None:
        """As plugging it back in: a new pty behind the same link."""
        if not self.plugged:
            self.open()

    def read(self) -> bytes:
        """Whatever the adapter wrote since the last read (never blocks)."""
        if self.master is None:
            return b""
        try:
            return os.read(self.master, 4096)
        except BlockingIOError:
            return b""
        except OSError as err:
            if err.errno == errno.EIO:  # nobody has the slave open
                return b""
            raise

    def write(self, data: bytes) -> None:
        """Send bytes through the line's noise; what the kernel cannot buffer is dropped."""
        if self.master is None or not data:
            return
        data = self.noise(data)
        try:
            n = os.write(self.master, data)
        except BlockingIOError:
            n = 0
        except OSError as err:
            if err.errno != errno.EIO:
                raise
            n = 0
        self.written += n
        self.dropped += len(data) - n

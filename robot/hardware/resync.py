"""What both serial readers share: dropping bytes while out of step, and counting the resynchronisations."""

from __future__ import annotations

from dataclasses import dataclass, field


@dataclass
class ResyncStats:
    """Bytes fed, bytes dropped out of step, and runs of dropped bytes (one per loss of sync)."""

    bytes: int = 0
    skipped: int = 0
    resyncs: int = 0


@dataclass
class ResyncBuffer:
    """A receive buffer that drops bytes from its front while the reader looks for the next frame.

    The first byte dropped after a good frame counts a resynchronisation;
    :meth:`synced` marks a good frame.
    """

    buf: bytearray = field(default_factory=bytearray)
    in_sync: bool = True

    def skip(self, n: int, stats: ResyncStats) -> None:
        if n <= 0:
            return
        if self.in_sync:
            stats.resyncs += 1
            self.in_sync = False
        stats.skipped += n
        del self.buf[:n]

    def synced(self) -> None:
        self.in_sync = True

"""A serial device read by a background thread, noticed when lost and reopened when it comes back.

Both the Kobuki base and the RPLIDAR are USB-serial devices that stream
bytes on their own. :class:`SerialDevice` owns the port (pyserial, opened
exclusively so a second program cannot steal it), reads whatever arrives in
a thread and hands it, stamped with the adapter's clock, to ``on_bytes``.
The device is *lost* when the port fails (unplugged: the read raises) or
when nothing has arrived for ``silence`` seconds (the cable is in but the
device is dead); the thread then closes the port and tries to reopen it
every ``retry`` seconds, calling ``on_connect`` when it succeeds (the lidar
starts its scan again there). kobuki_core's driver does the same (its
``spin()`` reopens the port and flags ``is_alive`` after 0.1 s of silence).

The first open, in :meth:`open`, is the one that may fail loudly: a missing
or busy port raises :class:`DeviceError` with a one-line reason.
"""

from __future__ import annotations

import threading
from collections.abc import Callable

import serial  # type: ignore[import-untyped]

READ_TIMEOUT = 0.02  # [s] a read returns after this long with whatever arrived
DEFAULT_SILENCE = 0.5  # [s] no byte for this long: the device is lost
DEFAULT_RETRY = 0.5  # [s] between attempts to reopen a lost port


class DeviceError(Exception):
    """A device cannot be opened: missing, busy or not a serial port (the message is one line)."""


def open_port(port: str, baud: int, timeout: float = READ_TIMEOUT) -> serial.Serial:
    """Open ``port`` at ``baud`` 8N1, exclusively; DeviceError with a one-line reason if it cannot."""
    try:
        return serial.Serial(port, baud, timeout=timeout, write_timeout=1.0, exclusive=True)
    except serial.SerialException as err:
        text = str(err)
        errno = getattr(err, "errno", None)
        if errno == 2 or "No such file" in text:
            raise DeviceError("no such device (is it plugged in?)") from None
        if "exclusively lock" in text or errno in (11, 16):
            raise DeviceError("busy: another program has it open") from None
        if errno == 13 or "Permission denied" in text:
            raise DeviceError("permission denied (add yourself to the 'dialout' group)") from None
        raise DeviceError(text.splitlines()[0] if text else type(err).__name__) from None
    except (OSError, ValueError) as err:
        raise DeviceError(str(err).splitlines()[0]) from None


class SerialDevice:
    """A port read in a thread: ``on_bytes(chunk, stamp)`` for every chunk, reopened when lost.

    ``now`` is the adapter's clock [s]. Subclasses override :meth:`on_bytes`
    and :meth:`on_connect`; they run on the reader thread, so they guard
    shared state with :attr:`lock`.
    """

    def __init__(self, name: str, port: str, baud: int, now: Callable[[], float],
                 silence: float = DEFAULT_SILENCE, retry: float = DEFAULT_RETRY):
        self.name = name
        self.port = port
        self.baud = baud
        self.now = now
        self.silence = silence
        self.retry = retry
        self.lock = threading.RLock()
        self._write_lock = threading.Lock()
        self._serial: serial.Serial | None = None
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None
        self.last_byte = -float("inf")  # [s] adapter clock
        self.connected = False
        self.reconnects = 0
        self.losses = 0

    # --- lifecycle ---------------------------------------------------------------------------
    def open(self) -> None:
        """Open the port and start reading; DeviceError if the port is missing or busy."""
        self._serial = open_port(self.port, self.baud)
        self.connected = True
        self.last_byte = self.now()
        try:
            self.on_connect()
        except DeviceError:
            self._close_port()
            raise
        self._thread = threading.Thread(target=self._run, name=f"homing-{self.name}", daemon=True)
        self._thread.start()

    def close(self) -> None:
        """Stop the reader thread and close the port."""
        self._stop.set()
        if self._thread is not None:
            self._thread.join(timeout=2.0)
        self._close_port()

    @property
    def lost(self) -> bool:
        """True when the port is gone or silent for longer than ``silence``."""
        return not self.connected or self.now() - self.last_byte > self.silence

    def write(self, data: bytes) -> bool:
        """Send bytes; False (nothing sent) when the port is not open or the write fails."""
        with self._write_lock:
            ser = self._serial
            if ser is None or not self.connected:
                return False
            try:
                ser.write(data)
                return True
            except (serial.SerialException, OSError):
                return False

    # --- to override -------------------------------------------------------------------------------
    def on_bytes(self, chunk: bytes, stamp: float) -> None:
        """Bytes arrived at ``stamp`` [s] (reader thread)."""

    def on_connect(self) -> None:
        """The port was (re)opened (reader thread, or :meth:`open`'s caller)."""

    # --- the reader thread ---------------------------------------------------------------------------
    def _run(self) -> None:
        while not self._stop.is_set():
            ser = self._serial
            if ser is None:
                if self._stop.wait(self.retry):
                    break
                self._reopen()
                continue
            try:
                chunk = ser.read(max(1, ser.in_waiting))
            except (serial.SerialException, OSError, TypeError):
                self._lose()
                continue
            if chunk:
                stamp = self.now()
                self.last_byte = stamp
                self.on_bytes(chunk, stamp)
            elif self.now() - self.last_byte > max(self.silence, 4 * self.retry):
                self._lose()  # silent too long: reopen, in case the device came back on a new line

    def _lose(self) -> None:
        if self.connected:
            self.losses += 1
        self.connected = False
        self._close_port()

    def _reopen(self) -> None:
        try:
            ser = open_port(self.port, self.baud)
        except DeviceError:
            return
        with self._write_lock:
            self._serial = ser
        self.connected = True
        self.last_byte = self.now()
        self.reconnects += 1
        try:
            self.on_connect()
        except DeviceError:
            self._lose()

    def _close_port(self) -> None:
        with self._write_lock:
            ser, self._serial = self._serial, None
        if ser is not None:
            try:
                ser.close()
            except (serial.SerialException, OSError):
                pass

"""Base classes for homing's leaves: blackboard access, the adapter's clock, and long actions.

:class:`HomingBehaviour` is what every leaf may derive from: it registers the
blackboard keys the class declares (``READS``/``WRITES``, the same tuples the
mission compiler checks), receives the robot adapter and the run's seed in
``setup(robot=..., seed=...)`` (ARCHITECTURE.md, one tick), and reads time
only from the adapter's clock.

:class:`LongAction` is the one base class for actions that take many ticks
(navigate, explore, dock, turn), after Nav2's ``BtActionNode``: it owns the
deadline (adapter clock, seconds) and cancellation, and a subclass fills in
``on_start``, ``on_running``, ``on_success``, ``on_failure`` and
``on_cancel``. It never blocks a tick: ``on_running`` polls and returns.

:func:`drive` writes ``/cmd_vel``; the runner sends it after the tick (zero
if no leaf wrote it), so a leaf that stops being ticked stops the robot.
"""

from __future__ import annotations

import math
import zlib
from collections.abc import Iterable
from typing import Any, ClassVar

import numpy as np
import py_trees
from homing.behaviours.keys import CMD_VEL_KEY, OBSERVATION_KEY, TIME_KEY
from homing.behaviours.registry import Param
from homing.robot import Observation, RobotAdapter, Twist2
from py_trees.common import Access, Status

TIME_SLACK = 1e-6  # [s] sums of float time steps fall short of round durations by this much at most

TIMEOUT_PARAM = Param(
    "timeout", float, 0.0, "s", "give up (FAILURE, reason 'timed_out') after this long on the adapter clock; 0 = never",
    minimum=0.0,
)


def drive(client: py_trees.blackboard.Client, v: float, omega: float) -> Twist2:
    """Write a velocity command [m/s, rad/s] in ``base_link`` to ``/cmd_vel`` for this tick.

    The client needs WRITE access to ``/cmd_vel`` (declare it in ``WRITES``).
    The adapter clips it to the robot's limits; the runner sends zero on a
    tick where no leaf wrote it, so there is no need to "stop" explicitly
    when a behaviour finishes or is halted.
    """
    cmd = Twist2(float(v), float(omega))
    client.set(CMD_VEL_KEY, cmd, overwrite=True)
    return cmd


class HomingBehaviour(py_trees.behaviour.Behaviour):
    """A leaf that declares its parameters and blackboard keys and lives on the adapter's clock.

    Subclasses set ``PARAMS``, ``READS`` and ``WRITES`` (class attributes, read
    by :func:`homing.behaviours.registry.register`; ``OPTIONAL_READS`` for keys
    some trees never write) and take their parameters
    as keyword arguments of ``__init__(name, ...)``. Keys in ``READS`` and
    ``WRITES`` are registered on ``self.bb`` here; a key given as
    ``"$param"`` is resolved from the attribute of that name, so set it
    before calling ``super().__init__``.

    Do not use for decorators or composites (those wrap children; see
    :mod:`homing.behaviours.decorators`).
    """

    PARAMS: ClassVar[tuple[Param, ...]] = ()
    READS: ClassVar[tuple[str, ...]] = ()
    WRITES: ClassVar[tuple[str, ...]] = ()
    # Read when another node writes them, unset otherwise (BT.CPP's optional input port): ``homing check``
    # does not ask for a writer, and ``read`` gives its default while nothing has written the key.
    OPTIONAL_READS: ClassVar[tuple[str, ...]] = ()

    def __init__(self, name: str, **_: Any) -> None:
        super().__init__(name=name)
        self.robot: RobotAdapter | None = None
        self.seed: int = 0
        self.bb = self.attach_blackboard_client(name=name)
        for key in self._keys((*self.READS, *self.OPTIONAL_READS)):
            self.bb.register_key(key=key, access=Access.READ)
        for key in self._keys(self.WRITES):
            self.bb.register_key(key=key, access=Access.WRITE)

    def _keys(self, keys: Iterable[str]) -> list[str]:
        return [str(getattr(self, k[1:])) if k.startswith("$") else k for k in keys]

    def setup(self, **kwargs: Any) -> None:
        """Take the adapter (``robot=``) and the run's seed (``seed=``) handed down by the runner."""
        self.robot = kwargs.get("robot", self.robot)
        self.seed = int(kwargs.get("seed", self.seed) or 0)

    # -- time and randomness ------------------------------------------------
    def now(self) -> float:
        """The adapter's time [s]; falls back to ``/robot/time`` when no adapter was given."""
        if self.robot is not None:
            return float(self.robot.clock.now())
        return float(self.read(TIME_KEY, 0.0))

    def rng(self) -> np.random.Generator:
        """A generator derived from the run's seed and this node's name: runs repeat exactly."""
        return np.random.default_rng([self.seed, zlib.crc32(self.name.encode())])

    # -- blackboard ------------------------------------------------------------
    def read(self, key: str, default: Any = None) -> Any:
        """The value at ``key`` (declared in ``READS`` or ``WRITES``), or ``default`` if unset."""
        try:
            return self.bb.get(key)
        except KeyError:
            return default

    def write(self, key: str, value: Any) -> None:
        """Set ``key`` (declared in ``WRITES``)."""
        self.bb.set(key, value, overwrite=True)

    def observation(self) -> Observation | None:
        """This tick's observation (needs ``/robot/observation`` in ``READS``)."""
        return self.read(OBSERVATION_KEY)

    def drive(self, v: float, omega: float) -> Twist2:
        """Command (v [m/s], ω [rad/s]) this tick (needs ``/cmd_vel`` in ``WRITES``)."""
        return drive(self.bb, v, omega)


class LongAction(HomingBehaviour):
    """An action over many ticks with a deadline and cancellation, after Nav2's ``BtActionNode``.

    The lifecycle, on the adapter's clock:

    - ``initialise``: records ``start_time``, sets ``deadline`` (``timeout``
      seconds later; ``0`` = none; BT.CPP counts milliseconds, homing seconds)
      and calls :meth:`on_start`. A status returned there ends the action on
      this same tick (e.g. FAILURE for a goal that cannot be reached).
    - ``update``: past the deadline → :meth:`on_cancel`, reason
      ``"timed_out"``, then :meth:`on_failure`. Otherwise :meth:`on_running`
      polls the work; SUCCESS goes through :meth:`on_success`, FAILURE through
      :meth:`on_failure` (each may change the verdict).
    - ``terminate(INVALID)`` while running (a higher priority preempted it, a
      guard turned false, Ctrl-C) → :meth:`on_cancel`, reason ``"cancelled"``.

    ``failure_reason`` is a short typed cause (``"timed_out"``,
    ``"cancelled"``, or what :meth:`fail` was given, e.g. ``"no_path"``) so
    recoveries can choose by cause (STYLE.md, rule 6). Subclasses declare
    ``TIMEOUT_PARAM`` in ``PARAMS`` to let missions set the timeout and pass
    ``timeout=`` to ``super().__init__``.

    Do not block in any hook: start the work, then poll it tick by tick.
    """

    def __init__(self, name: str, timeout: float = 0.0, **kwargs: Any) -> None:
        super().__init__(name, **kwargs)
        self.timeout = float(timeout)  # [s], 0 = no deadline
        self.start_time = 0.0  # [s] adapter clock
        self.deadline = math.inf  # [s] adapter clock
        self.failure_reason: str | None = None
        self._early: Status | None = None

    # -- hooks for subclasses ------------------------------------------------
    def on_start(self) -> Status | None:
        """Start the work (send the goal). Return None to go on, or a status to finish now."""
        return None

    def on_running(self) -> Status:
        """Poll the work once; return RUNNING, SUCCESS or FAILURE. Must not block."""
        return Status.RUNNING

    def on_success(self) -> Status:
        """The work succeeded; return the final status (SUCCESS unless a check fails)."""
        return Status.SUCCESS

    def on_failure(self) -> Status:
        """The work failed or timed out (see ``failure_reason``); return the final status."""
        return Status.FAILURE

    def on_cancel(self) -> None:
        """Cancel the work still in progress (halted or timed out). Stopping the wheels is automatic."""

    # -- helpers -----------------------------------------------------------------
    def elapsed(self) -> float:
        """Seconds of adapter time since the action started."""
        return self.now() - self.start_time

    def has_run_for(self, seconds: float) -> bool:
        """Whether ``seconds`` of adapter time have passed since the start (ten steps of 0.1 s make 1 s, not 0.99…)."""
        return self.elapsed() >= seconds - TIME_SLACK

    def remaining(self) -> float:
        """Seconds left before the deadline (inf without one)."""
        return self.deadline - self.now()

    def fail(self, reason: str, message: str = "") -> Status:
        """Record a typed failure cause and return FAILURE (use from ``on_running``/``on_start``)."""
        self.failure_reason = reason
        self.feedback_message = message or reason
        return Status.FAILURE

    # -- py_trees lifecycle ------------------------------------------------------
    def initialise(self) -> None:
        self.start_time = self.now()
        self.deadline = self.start_time + self.timeout if self.timeout > 0 else math.inf
        self.failure_reason = None
        self.feedback_message = ""
        self._early = self.on_start()

    def update(self) -> Status:
        if self._early is not None:
            status, self._early = self._early, None
        elif self.now() >= self.deadline:
            self.on_cancel()
            self.failure_reason = "timed_out"
            self.feedback_message = f"timed out after {self.timeout:g} s"
            status = Status.FAILURE
        else:
            status = self.on_running()
        if status == Status.SUCCESS:
            return self.on_success()
        if status == Status.FAILURE:
            if self.failure_reason is None:
                self.failure_reason = "failed"
            return self.on_failure()
        return status

    def terminate(self, new_status: Status) -> None:
        if new_status == Status.INVALID and self.status == Status.RUNNING:
            self.failure_reason = "cancelled"
            self.on_cancel()

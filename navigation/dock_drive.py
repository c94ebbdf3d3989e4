"""IR auto-docking after kobuki's ``dock_drive`` (Yujin Robot, kobuki_core): three receivers, six bit codes, the charger.

The dock's three emitters light three regions in front of it, each split into
a near and a far sub-field (:class:`homing.robot.types.IR`); the robot's
receivers (right, centre, left) report which sub-fields they sit in while they
face the dock. Seen from above, dock at the bottom, looking out into the room::

        FAR_LEFT   | FAR_CENTER |  FAR_RIGHT          left/right are the dock's:
                   \\     |     /                        standing at the dock looking
       NEAR_LEFT    \\ NEAR_C. /   NEAR_RIGHT          out, the left region is on
                     \\   |   /                         your left
                     [  dock  ]

Kobuki's state machine, kept as it is (``dock_drive_states.cpp``), on the
receivers' codes OR-ed over the last ``WINDOW`` seconds (its 20 samples at
50 Hz), and on odometry for how far it has turned:

1. SCAN: turn on the spot. The centre receiver seeing a CENTER code means the
   robot faces the dock from inside the centre beam: ALIGNED. Seeing a LEFT
   or RIGHT code records on which side of the beam the robot stands. After a
   full turn without the centre beam: FIND_STREAM.
2. FIND_STREAM: turn until the receiver on the dock's side sees the region the
   robot stands in, i.e. until the robot drives parallel to the dock's face
   towards the centre line; GET_STREAM.
3. GET_STREAM: creep forward until that receiver sees the *other* side's code
   (the robot has crossed the centre line); SCAN again, slowly, to face the dock.
4. ALIGNED (FAR / NEAR): drive in, steering towards the centre while the
   centre receiver sees a side code; back to SCAN when it sees nothing.
5. Charging reported by the base (not a pose!): DOCKED_IN, stop; DONE once it
   has held for ``SETTLE``. A bumper press: BUMPED, back off, SCAN.

Where homing departs from kobuki, each because kobuki's robot can stall there:

- a full SCAN turn that saw no code at all, or a FIND_STREAM with no side
  recorded (kobuki has no branch for it and stands still), ends in LOST with
  reason ``no_signal``; no code at all for ``LOST_TIME`` in any state too;
- ``MAX_BUMPS`` presses end in FAILED with reason ``bumped`` (kobuki backs off
  and rescans for ever);
- every reason is typed, so the caller can back off to the staging pose and
  try again (the mission's recovery, thesis §3.3.5);
- the centre beam lost while aligned, SCAN turns back against the last
  steering (kobuki always turns counter-clockwise, often most of a turn: over
  40 starts near the staging pose the slowest docking took 38 s against 55);
- started on the staging pose at a known ``approach`` distance, facing the
  dock, the robot drives in at ``APPROACH_V`` until odometry puts it within
  ``SLOW_ZONE`` of the docked pose, and at kobuki's speeds from there or after
  any rescan or bump (kobuki creeps the whole near field, 0.8 m, at 5 cm/s:
  18 s from a 1 m staging pose; 6.5 s this way after the tag servo, in
  ``homing world dock lab``); the contacts are still met at kobuki's 5 cm/s.
  When the tag servo has just put it there (its distance known to
  centimetres, not to the map's drift), the zone is ``SERVOED_SLOW_ZONE``.
  Over the 100 runs of ``homing bench dock``, paired by seed: ``APPROACH_V``
  0.20 m/s rather than 0.15 saved 1.2 s (median of the paired differences;
  97 runs faster), the servoed zone 0.12 m rather than 0.20 another 1.2 s
  (78 faster, the slower ones by rescans of up to 3 s); from a map-only
  staging pose a zone shorter than 0.3 m cost up to 8 s in rescans.

It never blocks: call :meth:`DockDrive.step` once a tick with that tick's
observation; it returns the command. ``homing world dock lab`` prints a trace
of a docking in the simulator (the tag servo, then this drive).
"""

from __future__ import annotations

import enum
import math
from collections import deque
from dataclasses import dataclass

from homing.robot import Bumpers, DockIR, Pose2, Twist2
from homing.robot.frames import wrap_angle
from homing.robot.types import IR

WINDOW = 0.4  # [s] receivers' codes OR-ed over this long (kobuki: 20 samples at 50 Hz)
SCAN_OMEGA = 0.66  # [rad/s] searching turn (kobuki)
SLOW_OMEGA = 0.10  # [rad/s] turn while the centre receiver sees the dock but not its centre beam (kobuki)
FIND_OMEGA = 0.33  # [rad/s] turning towards the centre line (kobuki)
STREAM_V = 0.05  # [m/s] creeping across to the centre line (kobuki)
FAR_V = 0.10  # [m/s] approach in the far field (kobuki)
FAR_OMEGA = 0.30  # [rad/s] steering in the far field (kobuki)
NEAR_V = 0.05  # [m/s] approach in the near field (kobuki)
NEAR_OMEGA = 0.10  # [rad/s] steering in the near field (kobuki)
BUMP_V = -0.05  # [m/s] backing off a bump (kobuki)
BUMP_TIME = 0.4  # [s] backing off a bump (kobuki: 10 cycles at 50 Hz; twice that here, so the rim clears)
SETTLE = 0.4  # [s] charging must hold this long before DONE (kobuki: 20 cycles)
LOST_TIME = 30.0  # [s] no code on any receiver this long: LOST (a slow full turn takes 19 s)
APPROACH_V = 0.20  # [m/s] driving in from a known staging distance (see the module doc)
SLOW_ZONE = 0.30  # [m] kobuki's speeds this close to the docked pose
SERVOED_SLOW_ZONE = 0.12  # [m] the same when the tag servo has just put the robot on the staging pose
STREAM_MAX = 2.5  # [m] creeping this far without crossing the centre line: LOST
MAX_BUMPS = 3  # presses before the attempt fails (kobuki: no limit)
FULL_TURN = 2.0 * math.pi  # [rad]

NEAR = IR.NEAR_LEFT | IR.NEAR_CENTER | IR.NEAR_RIGHT
FAR = IR.FAR_LEFT | IR.FAR_CENTER | IR.FAR_RIGHT
LEFT = IR.NEAR_LEFT | IR.FAR_LEFT
RIGHT = IR.NEAR_RIGHT | IR.FAR_RIGHT
CENTER = IR.NEAR_CENTER | IR.FAR_CENTER


class DockState(enum.Enum):
    """Where the docking drive is (kobuki's ``RobotDockingState`` plus LOST and FAILED)."""

    SCAN = "scan"
    FIND_STREAM = "find_stream"
    GET_STREAM = "get_stream"
    ALIGNED = "aligned"
    ALIGNED_FAR = "aligned_far"
    ALIGNED_NEAR = "aligned_near"
    BUMPED = "bumped"
    DOCKED_IN = "docked_in"
    DONE = "done"
    LOST = "lost"
    FAILED = "failed"

    @property
    def finished(self) -> bool:
        return self in (DockState.DONE, DockState.LOST, DockState.FAILED)


@dataclass
class DockTrace:
    """One step of a docking, for pictures and tests: time [s], state, filtered codes (right, centre, left), command."""

    time: float
    state: DockState
    codes: tuple[int, int, int]
    cmd: Twist2


class DockDrive:
    """Kobuki's IR docking state machine (see the module doc). One docking attempt per :meth:`start`.

    ``reason`` is set when the attempt ends unsuccessfully: ``no_signal``
    (LOST) or ``bumped`` (FAILED). ``trace`` keeps every step when
    ``keep_trace`` is set.
    """

    def __init__(self, window: float = WINDOW, max_bumps: int = MAX_BUMPS, lost_time: float = LOST_TIME,
                 keep_trace: bool = False) -> None:
        self.window = float(window)  # [s]
        self.max_bumps = int(max_bumps)
        self.lost_time = float(lost_time)  # [s]
        self.keep_trace = keep_trace
        self.trace: list[DockTrace] = []
        self.start(0.0, Pose2())

    def start(self, now: float, odom: Pose2, approach: float = 0.0, slow_zone: float = SLOW_ZONE) -> None:
        """Begin an attempt at time ``now`` [s] from odometry pose ``odom``.

        ``approach`` [m]: the robot starts on the staging pose this far straight out from the docked pose,
        facing the dock (0: unknown). Then, until its first rescan or bump, it drives in at ``APPROACH_V`` while
        odometry puts it more than ``slow_zone`` [m] from the docked pose, and at kobuki's speeds after that.
        """
        self._docked_at = odom.compose(Pose2(approach, 0.0, 0.0)) if approach > 0 else None
        self.slow_zone = float(slow_zone)
        self.state = DockState.SCAN
        self.reason: str | None = None
        self.message = "scanning for the dock"
        self.dock_side = 0  # > 0: the robot stands in the dock's right region, < 0: its left (kobuki's dock_detector)
        self.turned = 0.0  # [rad] turned since the last SCAN began
        self.bumps = 0
        self._odom = odom
        self.scan_dir = 1.0  # +1: SCAN turns counter-clockwise (kobuki), -1: clockwise
        self._steer = 0.0  # sign of the last steering while aligned
        self._past: deque[tuple[float, DockIR]] = deque()
        self._last_yaw = odom.theta
        self._last_seen = now
        self._state_since = now
        self._charging_since: float | None = None
        self.trace.clear()

    # ----------------------------------------------------------------------------- inputs
    def filtered(self, now: float, ir: DockIR) -> tuple[IR, IR, IR]:
        """(right, centre, left) codes OR-ed over the last ``window`` seconds, this sample included."""
        self._past.append((now, ir))
        while self._past and self._past[0][0] < now - self.window + 1e-9:
            self._past.popleft()
        right = centre = left = IR.NONE
        for _, sample in self._past:
            right |= sample.right
            centre |= sample.centre
            left |= sample.left
        return right, centre, left

    def step(self, now: float, ir: DockIR, bumpers: Bumpers, charging: bool, odom: Pose2) -> Twist2:
        """One tick: the receivers' raw codes, bumpers, whether the base reports charging, odometry pose."""
        turn = wrap_angle(odom.theta - self._last_yaw)
        self._last_yaw = odom.theta
        self._odom = odom
        right, centre, left = self.filtered(now, ir)
        if ir.any():
            self._last_seen = now
        if self.state.finished:
            cmd = Twist2()
        elif charging or bumpers.any():
            cmd = self._bump_or_charge(now, bumpers.any(), charging)
        elif now - self._last_seen >= self.lost_time and self.state is not DockState.BUMPED:
            cmd = self._end(DockState.LOST, "no_signal", f"no dock signal for {self.lost_time:g} s")
        else:
            self._charging_since = None
            cmd = self._drive(now, right, centre, left, turn)
        if self.keep_trace:
            self.trace.append(DockTrace(now, self.state, (int(right), int(centre), int(left)), cmd))
        return cmd

    # ------------------------------------------------------------------------ the states
    def _bump_or_charge(self, now: float, bumped: bool, charging: bool) -> Twist2:
        if charging and not bumped:
            # The base says the contacts are closed: stop and wait for it to hold (kobuki's DOCKED_IN).
            if self._charging_since is None:
                self._charging_since = now
            if now - self._charging_since >= SETTLE - 1e-9:
                self._set(DockState.DONE, now, "docked: charging")
            else:
                self._set(DockState.DOCKED_IN, now, "contacts closed, settling")
            return Twist2()
        if charging:  # charging but pressing on the dock: ease off a little (kobuki's BUMPED_DOCK)
            return Twist2(-0.01, 0.0)
        self.bumps += 1
        self._docked_at = None
        if self.bumps >= self.max_bumps:
            return self._end(DockState.FAILED, "bumped", f"bumped {self.bumps} times")
        self._set(DockState.BUMPED, now, f"bumped ({self.bumps}), backing off")
        return Twist2(BUMP_V, 0.0)

    def _drive(self, now: float, right: IR, centre: IR, left: IR, turn: float) -> Twist2:
        s = self.state
        if s is DockState.BUMPED:
            if now - self._state_since < BUMP_TIME - 1e-9:
                return Twist2(BUMP_V, 0.0)
            return self._rescan(now, SCAN_OMEGA)
        if s is DockState.SCAN:
            return self._scan(now, centre, turn)
        if s is DockState.FIND_STREAM:
            return self._find_stream(now, right, left, turn)
        if s is DockState.GET_STREAM:
            return self._get_stream(now, right, left)
        return self._aligned(now, centre)

    def _scan(self, now: float, centre: IR, turn: float) -> Twist2:
        self.turned += turn
        if centre & CENTER:
            self._set(DockState.ALIGNED, now, "facing the centre beam")
            return Twist2(NEAR_V, 0.0)
        if centre & LEFT:
            self.dock_side -= 1
            return Twist2(0.0, self.scan_dir * SCAN_OMEGA)
        if centre & RIGHT:
            self.dock_side += 1
            return Twist2(0.0, self.scan_dir * SCAN_OMEGA)
        if centre:  # a code with no side bit cannot happen; kobuki turns slowly on it
            return Twist2(0.0, self.scan_dir * SLOW_OMEGA)
        if abs(self.turned) > FULL_TURN:
            if self.dock_side == 0:
                return self._end(DockState.LOST, "no_signal", "a full turn without seeing the dock")
            self.turned = 0.0
            self._set(DockState.FIND_STREAM, now, "turning towards the centre line")
            return Twist2()
        self.message = f"scanning, turned {math.degrees(abs(self.turned)):.0f}°"
        return Twist2(0.0, self.scan_dir * SCAN_OMEGA)

    def _find_stream(self, now: float, right: IR, left: IR, turn: float) -> Twist2:
        self.turned += turn
        if abs(self.turned) > FULL_TURN:
            return self._end(DockState.LOST, "no_signal", "a full turn without finding the dock's side beam")
        if self.dock_side > 0:  # in the dock's right region: turn clockwise until the left receiver sees it
            if left & RIGHT:
                self._set(DockState.GET_STREAM, now, "crossing to the centre line")
                return Twist2(STREAM_V, 0.0)
            return Twist2(0.0, -FIND_OMEGA)
        if right & LEFT:  # in the dock's left region: counter-clockwise until the right receiver sees it
            self._set(DockState.GET_STREAM, now, "crossing to the centre line")
            return Twist2(STREAM_V, 0.0)
        return Twist2(0.0, FIND_OMEGA)

    def _get_stream(self, now: float, right: IR, left: IR) -> Twist2:
        if (now - self._state_since) * STREAM_V > STREAM_MAX:
            return self._end(DockState.LOST, "no_signal", f"crept {STREAM_MAX:g} m without crossing the centre line")
        crossed = (left & LEFT) if self.dock_side > 0 else (right & RIGHT)
        if crossed:
            return self._rescan(now, SLOW_OMEGA)
        return Twist2(STREAM_V, 0.0)

    def _aligned(self, now: float, centre: IR) -> Twist2:
        if not centre:
            d = -self._steer if self._steer else 1.0
            return self._rescan(now, SCAN_OMEGA, d)
        if (centre & NEAR) in (IR.NEAR_CENTER, NEAR):
            self._set(DockState.ALIGNED_NEAR, now, "near, on the centre beam")
            self._steer = 0.0
            return Twist2(self._speed(NEAR_V), 0.0)
        if centre & IR.NEAR_LEFT:  # the dock's left: turn counter-clockwise, towards the centre line
            self._set(DockState.ALIGNED_NEAR, now, "near, left of the centre beam")
            self._steer = +1.0
            return Twist2(self._speed(NEAR_V), NEAR_OMEGA)
        if centre & IR.NEAR_RIGHT:
            self._set(DockState.ALIGNED_NEAR, now, "near, right of the centre beam")
            self._steer = -1.0
            return Twist2(self._speed(NEAR_V), -NEAR_OMEGA)
        if (centre & FAR) in (IR.FAR_CENTER, FAR):
            self._set(DockState.ALIGNED_FAR, now, "far, on the centre beam")
            self._steer = 0.0
            return Twist2(self._speed(FAR_V), 0.0)
        if centre & IR.FAR_LEFT:
            self._set(DockState.ALIGNED_FAR, now, "far, left of the centre beam")
            self._steer = +1.0
            return Twist2(self._speed(FAR_V), FAR_OMEGA)
        if centre & IR.FAR_RIGHT:
            self._set(DockState.ALIGNED_FAR, now, "far, right of the centre beam")
            self._steer = -1.0
            return Twist2(self._speed(FAR_V), -FAR_OMEGA)
        return self._rescan(now, SCAN_OMEGA)

    # ------------------------------------------------------------------------- helpers
    def _speed(self, v: float) -> float:
        """Forward speed [m/s] in an aligned state: kobuki's ``v``, or APPROACH_V on the way in from staging."""
        if self._docked_at is None:
            return v
        d = math.hypot(self._docked_at.x - self._odom.x, self._docked_at.y - self._odom.y)
        return max(v, APPROACH_V) if d > self.slow_zone else v

    def _rescan(self, now: float, omega: float, direction: float = 1.0) -> Twist2:
        self._docked_at = None  # off the straight way in: kobuki's speeds from here
        self.dock_side = 0
        self.turned = 0.0
        self.scan_dir = direction
        self._set(DockState.SCAN, now, "scanning for the dock")
        return Twist2(0.0, direction * omega)

    def _set(self, state: DockState, now: float, message: str) -> None:
        if state is not self.state:
            self._state_since = now
        self.state = state
        self.message = message

    def _end(self, state: DockState, reason: str, message: str) -> Twist2:
        self.state = state
        self.reason = reason
        self.message = message
        return Twist2()

"""The simulated TurtleBot 2: a kinematic Kobuki in a pybullet world, behind the robot adapter contract.

``SimRobot(world, seed=1)`` implements :class:`homing.robot.RobotAdapter`.
Each ``step(dt)`` runs sub-steps of at most ``physics_dt``; in each:

1. faults start or stop (:mod:`homing.sim.faults`);
2. the base moves kinematically along the arc of the clipped command
   (less a ``wheel_slip`` fault's share), then is pushed out of walls, fault
   obstacles and the dock's box; a penetration deeper than 1 mm presses the
   bumper of its sector (:func:`homing.robot.turtlebot.bumper_sector`);
3. the dock's guide centres a robot pushing into it (:meth:`Dock.funnel`);
4. the encoders measure the commanded wheel motion and the odometry adds
   slip noise (:mod:`homing.sim.odometry`), worse on low-friction patches;
5. the batteries drain, or charge while the contacts are closed;
6. the lidar scans at 5.5 Hz and the camera renders at ``camera_rate`` when
   a tag can be in view.

A step under a zero command with nothing moving in the world (no
``bumper_hit`` obstacle or ``kidnap`` due) is idle: it runs in sub-steps of
up to ``IDLE_DT`` and senses once at its end (the intermediate scans and
frames would be overwritten unread), so a robot charging on its dock for an
hour costs a few milliseconds of simulation per minute.

Every random draw comes from numpy Generators seeded from ``seed`` (one
stream per sensor), and time only from the simulated clock, so the same
world, seed and commands give byte-identical observations.

Ground truth (:meth:`truth_pose`, :meth:`set_truth_pose`, :attr:`charging`)
is for evaluation and tests only: behaviours and services must use
:meth:`observe`.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
from homing.robot.frames import wrap_angle
from homing.robot.turtlebot import LIDAR_RATE, RobotLimits, bumper_sector
from homing.robot.types import Bumpers, CameraImage, Observation, Odometry, Pose2, Scan, Twist2
from homing.sim.battery import Battery
from homing.sim.camera import CAMERA_RATE, HEIGHT, WIDTH, RenderedOnDemand, SimCamera
from homing.sim.dock import Dock
from homing.sim.events import Change, rasterise, safe_to_place
from homing.sim.faults import Fault
from homing.sim.lidar import SimLidar
from homing.sim.odometry import SlipModel, WheelOdometry, arc
from homing.sim.scene import BUMP_DEPTH, OBSTACLE_SIZE, Scene
from homing.sim.world import World

from homing.map_server import MapData

PHYSICS_DT = 0.05  # [s] longest sub-step: 35 mm at 0.7 m/s, under a wall's thickness
PUSH_ITERATIONS = 4  # collision resolution passes per sub-step
BUMP_HIT_SPEED = 0.5  # [m/s] a bumper_hit obstacle's approach speed
BUMP_HIT_BEARING = {"left": math.radians(60.0), "centre": 0.0, "right": math.radians(-60.0)}
KIDNAP_CLEARANCE = 0.35  # [m] a random kidnap lands at least this far from walls
IDLE_DT = 1.0  # [s] longest sub-step of an idle step (no command, nothing moving)
CAMERA_STREAM = 2  # seed stream of the camera's pixel noise (frame by frame)
MOVING_FAULTS = ("bumper_hit", "kidnap")
CHANGE_RETRY = 1.0  # [s] a world change held back (it would trap the robot) is tried again this often  # faults that move something: no idle step across them


class SimClock:
    """Simulated time [s]; advances only in :meth:`SimRobot.step`."""

    def __init__(self) -> None:
        self.t = 0.0

    def now(self) -> float:
        return self.t


class SimRobot:
    """A simulated TurtleBot 2 (implements :class:`homing.robot.RobotAdapter`).

    ``camera=False`` skips rendering entirely (images are None);
    ``faults`` add to those in the world file.
    """

    def __init__(
        self,
        world: World,
        seed: int = 0,
        camera: bool = True,
        faults: list[Fault] | tuple[Fault, ...] = (),
        changes: list[Change] | tuple[Change, ...] = (),
        camera_rate: float = CAMERA_RATE,
        image_size: tuple[int, int] = (WIDTH, HEIGHT),
        physics_dt: float = PHYSICS_DT,
        slip_model: SlipModel | None = None,
        start: Pose2 | None = None,
    ):
        self.world = world
        self.seed = int(seed)
        self.clock = SimClock()
        self.limits = RobotLimits()
        self.physics_dt = physics_dt
        streams = np.random.SeedSequence(self.seed).spawn(4)
        self._rng_odom, self._rng_lidar, _, self._rng_fault = (
            np.random.default_rng(s) for s in streams
        )
        self.scene = Scene(world, visuals=camera)
        self.lidar = SimLidar(self.scene)
        self.camera = SimCamera(self.scene, *image_size) if camera else None
        self.camera_period = 1.0 / camera_rate
        self.dock: Dock = world.dock
        self.faults = tuple(world.faults) + tuple(faults)
        self.changes = tuple(world.events) + tuple(changes)
        self._standing: dict[int, Change] = {}  # world changes in the scene now, by index
        self._next_change_check = -math.inf
        self._fault_started: set[int] = set()
        self._bump_obstacles: dict[int, tuple[float, float, float, float]] = {}
        self._pose = start or world.start
        self.odometry = WheelOdometry(self._rng_odom, slip_model)
        self.base_battery = Battery(world.battery_base)
        self.computer_battery = Battery(world.battery_computer)
        self._cmd = Twist2()
        self._bumpers = Bumpers()
        self._scan: Scan | None = None
        self._image: CameraImage | None = None
        self._next_scan = 0.0
        self._next_frame = 0.0
        self._frames = 0  # frames taken (rendered or not): each one's pixel noise is seeded by its number
        self._closed = False
        self._sense()

    # --- the adapter contract ----------------------------------------------------------------
    def observe(self) -> Observation:
        """One snapshot of all sensors at the current simulated time (never blocks)."""
        t = self.clock.now()
        on_dock = self.charging
        return Observation(
            stamp=t,
            odom=Odometry(t, self.odometry.pose, Twist2(self.odometry.v, self.odometry.omega)),
            scan=self._scan,
            image=self._image,
            bumpers=self._bumpers,
            dock_ir=self.dock.ir(self._pose, self._ir_clear),
            battery=self.base_battery.state(on_dock),
            computer_battery=self.computer_battery.state(on_dock),
        )

    def command(self, v: float, omega: float) -> Twist2:
        """Set the velocity command [m/s, rad/s], clipped to the Kobuki's limits; held until replaced."""
        cv, cw = self.limits.clip(v, omega)
        self._cmd = Twist2(cv, cw)
        return self._cmd

    def step(self, dt: float) -> None:
        """Advance the simulation by ``dt`` [s] under the current command."""
        if dt <= 0:
            return
        if self._idle(dt):
            n = max(1, math.ceil(dt / IDLE_DT - 1e-9))
            for _ in range(n):
                self._substep(dt / n, sense=False)
            self._catch_up_sensors()
            self._bumpers = Bumpers()
            return
        n = max(1, math.ceil(dt / self.physics_dt - 1e-9))
        h = dt / n
        pressed = {"left": False, "centre": False, "right": False}
        for _ in range(n):
            for side in self._substep(h):
                pressed[side] = True
        self._bumpers = Bumpers(pressed["left"], pressed["centre"], pressed["right"])

    def _idle(self, dt: float) -> bool:
        """Whether the step may be taken coarsely: no command, and nothing moving in the world during it."""
        if self._cmd.v != 0.0 or self._cmd.omega != 0.0 or dt <= self.physics_dt:
            return False
        t0, t1 = self.clock.t, self.clock.t + dt
        return not any(f.name in MOVING_FAULTS and f.at < t1 and f.at + max(f.length, 1e-9) > t0 for f in self.faults)

    def _catch_up_sensors(self) -> None:
        """After an idle step: of the scans and frames that fell due in it, take only the last, at its due time."""
        t = self.clock.t + 1e-9
        period = 1.0 / LIDAR_RATE
        if t >= self._next_scan:
            self._next_scan += math.floor((t - self._next_scan) / period) * period
            self._take_scan(min(self._next_scan, self.clock.t))
        if self.camera is not None and t >= self._next_frame:
            self._next_frame += math.floor((t - self._next_frame) / self.camera_period) * self.camera_period
            self._take_frame(min(self._next_frame, self.clock.t))

    def close(self) -> None:
        """Release the pybullet client."""
        if not self._closed:
            self.scene.close()
            self._closed = True

    # --- ground truth (evaluation only) ------------------------------------------------------
    def truth_pose(self) -> Pose2:
        """The robot's true base_link pose in the world. Evaluation and tests only."""
        return self._pose

    def set_truth_pose(self, pose: Pose2) -> None:
        """Teleport the robot (tests, kidnapping); odometry does not notice."""
        self._pose = pose

    @property
    def charging(self) -> bool:
        """Whether the dock's contacts are closed (truth)."""
        return self.dock.contacts_closed(self._pose)

    # --- one sub-step --------------------------------------------------------------------------
    def _substep(self, h: float, sense: bool = True) -> set[str]:
        t = self.clock.t
        self._apply_faults(t, h)
        if self.changes:
            self._apply_changes(t)
        v, w = self._cmd.v, self._cmd.omega
        keep = 1.0 - max((f.amount for f in self.faults if f.name == "wheel_slip" and f.active(t)), default=0.0)
        before = self._pose  # after a kidnap: the gyro feels real turns only
        pose = arc(self._pose, v * h * keep, w * h * keep)
        pose, sides = self._resolve(pose, v * keep)
        pose = self.dock.funnel(pose, v, h)
        self._pose = pose
        slip = max((p.slip for p in self.world.patches if p.contains(pose.x, pose.y)), default=1.0)
        # the encoders count the commanded wheel motion; the gyro feels the body's real turn (the dock's funnel too)
        self.odometry.update(v * h, w * h, h, slip, turned=wrap_angle(pose.theta - before.theta))
        on_dock = self.dock.contacts_closed(pose)
        self.base_battery.update(h, v, w, on_dock)
        self.computer_battery.update(h, v, w, on_dock)
        self.clock.t = t + h
        if sense:
            self._sense()
        if on_dock:
            sides.discard("centre")  # sitting on the contacts presses no bumper
        return sides

    def _resolve(self, pose: Pose2, v: float) -> tuple[Pose2, set[str]]:
        # A contact presses a bumper when the robot drives into it (v·cos(bearing) > 0) or when
        # a moving obstacle drives into the robot; resting or sliding along a wall presses none.
        sides: set[str] = set()
        moving = {self.scene.obstacles.get(f"bumper_hit{k}") for k in self._bump_obstacles}
        for _ in range(PUSH_ITERATIONS):
            hits = self.scene.penetrations(pose)
            pushed, dock_bearing = self.dock.push_out(pose)
            if dock_bearing is not None:
                hits.append((np.array([pushed.x - pose.x, pushed.y - pose.y]) / max(pose.distance_to(pushed), 1e-12),
                             pose.distance_to(pushed), dock_bearing, -1))
            if not hits:
                break
            n, depth, bearing, body = max(hits, key=lambda hit: hit[1])
            pose = Pose2(float(pose.x + n[0] * depth), float(pose.y + n[1] * depth), pose.theta)
            if depth > BUMP_DEPTH and (v * math.cos(bearing) > 1e-9 or body in moving):
                side = bumper_sector(bearing)
                if side is not None:
                    sides.add(side)
        return pose, sides

    def _sense(self) -> None:
        """Take the scan and the frame that are due now."""
        t = self.clock.t
        if t + 1e-9 >= self._next_scan:
            self._take_scan(t)
        if self.camera is not None and t + 1e-9 >= self._next_frame:
            self._take_frame(t)

    def _take_scan(self, at: float) -> None:
        burst = max((f.fraction for f in self.faults if f.name == "lidar_dropout" and f.active(at)), default=0.0)
        self._scan = self.lidar.scan(self._pose, at, self._rng_lidar, burst)
        self._next_scan += 1.0 / LIDAR_RATE

    def _take_frame(self, at: float) -> None:
        assert self.camera is not None
        self._next_frame += self.camera_period
        off = any(f.name == "camera_off" and f.active(at) for f in self.faults)
        if not off and self.camera.visible_tags(self._pose, self.world.tags):
            self._image = self._frame(self._pose, at)
        else:
            self._image = None

    def _frame(self, pose: Pose2, at: float) -> CameraImage:
        """The frame taken at ``pose`` and ``at`` [s], rendered when first read, with noise of its own seed."""
        camera = self.camera
        assert camera is not None
        self._frames += 1
        rng = np.random.default_rng([self.seed, CAMERA_STREAM, self._frames])
        return RenderedOnDemand(at, camera.info, lambda: camera.render(pose, at, rng).image)

    def render(self) -> CameraImage:
        """Render a frame now whatever is in view (demos, tests); does not change observations."""
        if self.camera is None:
            raise RuntimeError("this SimRobot was made with camera=False")
        return self.camera.render(self._pose, self.clock.t)

    def _ir_clear(self, starts: np.ndarray, ends: np.ndarray) -> np.ndarray:
        z = 0.06
        s3 = np.column_stack([starts, np.full(len(starts), z)])
        e3 = np.column_stack([ends, np.full(len(ends), z)])
        d = e3 - s3
        e3 = s3 + d * (1.0 - 0.03 / np.maximum(np.linalg.norm(d, axis=1, keepdims=True), 0.03))
        s3 = s3 + d * (0.01 / np.maximum(np.linalg.norm(d, axis=1, keepdims=True), 0.01))
        frac, ids = self.scene.rays(s3, e3)
        return (ids < 0) | (ids == self.scene.robot) | (frac >= 1.0)

    # --- faults --------------------------------------------------------------------------------------
    def _apply_faults(self, t: float, h: float) -> None:
        for k, f in enumerate(self.faults):
            if f.name == "kidnap" and k not in self._fault_started and t >= f.at:
                self._fault_started.add(k)
                self._pose = Pose2(*f.to) if f.to is not None else self._random_free_pose()
            elif f.name == "dock_obstacle":
                key = f"dock_obstacle{k}"
                if f.active(t) and key not in self.scene.obstacles:
                    spot = self.dock.emitter.compose(Pose2(f.distance + OBSTACLE_SIZE / 2, 0.0, 0.0))
                    self.scene.add_obstacle(key, spot.x, spot.y, spot.theta)
                elif not f.active(t) and key in self.scene.obstacles:
                    self.scene.remove_obstacle(key)
            elif f.name == "bumper_hit":
                self._bumper_hit(k, f, t, h)

    def _apply_changes(self, t: float) -> None:
        """World changes due now appear (when safe: not on the robot, not cutting it off its dock) or go."""
        for k, ch in enumerate(self.changes):
            if k in self._standing and not ch.present(t):
                del self._standing[k]
                self.scene.remove_obstacle(f"change{k}")
        due = [k for k, ch in enumerate(self.changes) if ch.present(t) and k not in self._standing]
        if not due or t < self._next_change_check:
            return
        self._next_change_check = t + CHANGE_RETRY  # a held-back change is tried again a little later
        for k in due:
            ch = self.changes[k]
            if safe_to_place(self.world.map, list(self._standing.values()), ch, self._pose, self.world.staging_pose(1.0)):
                self._standing[k] = ch
                self.scene.add_obstacle(f"change{k}", ch.x, ch.y, ch.yaw, ch.size)

    def state(self) -> dict[str, Any]:
        """The simulated world's state (JSON-able) for a run directory: time, the robot's truth, batteries, faults.

        Restored by :meth:`restore_state` on a new SimRobot of the same world, the world carries on where it
        was (the robot's odometry restarts at zero, as a restarted driver's does).
        """
        return {"t": self.clock.t, "pose": [self._pose.x, self._pose.y, self._pose.theta],
                "soc": [self.base_battery.soc, self.computer_battery.soc],
                "faults_started": sorted(self._fault_started), "frames": self._frames}

    def restore_state(self, state: dict[str, Any]) -> None:
        """Carry on from :meth:`state` (raises ValueError on a state that does not fit)."""
        try:
            t = float(state["t"])
            pose = Pose2(*(float(v) for v in state["pose"]))
            base, computer = (float(v) for v in state["soc"])
            started = {int(k) for k in state.get("faults_started", [])}
        except (KeyError, TypeError, ValueError) as err:
            raise ValueError(f"not a simulator state: {err}") from None
        if not (math.isfinite(t) and t >= 0 and 0 <= base <= 1 and 0 <= computer <= 1):
            raise ValueError("not a simulator state: time or charge out of range")
        self.clock.t = t
        self._pose = pose
        self.base_battery.soc, self.computer_battery.soc = base, computer
        self._fault_started = started
        self._frames = int(state.get("frames", 0))
        self._next_scan = self._next_frame = t
        self._sense()

    def truth_map(self) -> MapData:
        """The floor plan with the world changes standing now (evaluation: map agreement with the world as it is)."""
        return rasterise(self.world.map, list(self._standing.values()))

    def _bumper_hit(self, k: int, f: Fault, t: float, h: float) -> None:
        # The obstacle drives at the robot's position when the fault began, stops 1 cm inside
        # its rim (one press), waits, and vanishes when the fault ends.
        key = f"bumper_hit{k}"
        if f.active(t):
            if k not in self._bump_obstacles:
                bearing = self._pose.theta + BUMP_HIT_BEARING[f.side]
                start = self.limits.radius + OBSTACLE_SIZE / 2 + 0.25  # [m] from the robot's centre
                self._bump_obstacles[k] = (self._pose.x, self._pose.y, bearing, start)
                self.scene.add_obstacle(key, self._pose.x + start * math.cos(bearing),
                                        self._pose.y + start * math.sin(bearing), bearing)
            x0, y0, bearing, dist = self._bump_obstacles[k]
            dist = max(self.limits.radius + OBSTACLE_SIZE / 2 - 0.01, dist - BUMP_HIT_SPEED * h)
            self._bump_obstacles[k] = (x0, y0, bearing, dist)
            self.scene.move_obstacle(key, x0 + dist * math.cos(bearing), y0 + dist * math.sin(bearing), bearing)
        elif k in self._bump_obstacles:
            del self._bump_obstacles[k]
            self.scene.remove_obstacle(key)

    def _random_free_pose(self) -> Pose2:
        from homing.sim.walls import cell_to_world
        from scipy import ndimage

        reach = self.world.reachable_free()
        clearance = ndimage.distance_transform_edt(reach) * self.world.map.resolution
        rows, cols = np.nonzero(clearance >= KIDNAP_CLEARANCE)
        if rows.size == 0:
            return self._pose
        k = int(self._rng_fault.integers(rows.size))
        xy = cell_to_world(self.world.map, rows[k : k + 1], cols[k : k + 1])[0]
        yaw = float(self._rng_fault.uniform(-math.pi, math.pi))
        return Pose2(float(xy[0]), float(xy[1]), yaw)

"""A small scripted robot adapter and scripted leaves for the mission-language tests.

:class:`FakeRobot` implements :class:`homing.robot.RobotAdapter` with an exact
clock (time passes only in ``step``), a battery that drains linearly, and a
record of every command it was sent, so tests can assert that the robot was
stopped. :class:`Scripted` is a leaf that plays a list of statuses, one per
tick, and counts its ticks, starts and halts.
"""

from __future__ import annotations

import json
import os
from typing import Any

import numpy as np
import py_trees
from homing.robot import (
    BatteryState,
    Bumpers,
    DockIR,
    Observation,
    Odometry,
    Pose2,
    RobotLimits,
    Twist2,
)
from py_trees.common import Status

S, F, R = Status.SUCCESS, Status.FAILURE, Status.RUNNING


class FakeClock:
    def __init__(self, t: float = 0.0):
        self.t = t

    def now(self) -> float:
        return self.t


class FakeRobot:
    """An adapter with no physics: pose integrates the command, battery drains by ``drain`` %/s."""

    def __init__(self, seed: int = 0, battery: float = 90.0, drain: float = 0.0):
        self.clock = FakeClock(0.0)
        self.limits = RobotLimits()
        self.seed = seed
        self.battery = battery
        self.drain = drain  # [%/s]
        self.pose = Pose2()
        self.cmd = Twist2()
        self.commands: list[tuple[float, float, float]] = []
        self.closed = False

    def observe(self) -> Observation:
        t = self.clock.t
        return Observation(
            stamp=t,
            odom=Odometry(t, self.pose, self.cmd),
            scan=None,
            image=None,
            bumpers=Bumpers(),
            dock_ir=DockIR(),
            battery=BatteryState(voltage=15.0, percent=max(0.0, self.battery - self.drain * t)),
        )

    def command(self, v: float, omega: float) -> Twist2:
        self.cmd = Twist2(float(v), float(omega))
        self.commands.append((self.clock.t, self.cmd.v, self.cmd.omega))
        return self.cmd

    def step(self, dt: float) -> None:
        th = self.pose.theta
        self.pose = Pose2(self.pose.x + self.cmd.v * dt * np.cos(th), self.pose.y + self.cmd.v * dt * np.sin(th), th + self.cmd.omega * dt)
        self.clock.t = round(self.clock.t + dt, 9)

    def close(self) -> None:
        self.closed = True
        path = os.environ.get("HOMING_FAKE_ROBOT_LOG")
        if path:
            with open(path, "w") as f:
                json.dump({"commands": self.commands[-5:], "closed": True}, f)


def make_robot(seed: int = 0) -> FakeRobot:
    """Factory for ``homing run --adapter tests.mission_fakes:make_robot``."""
    return FakeRobot(seed=seed, battery=float(os.environ.get("HOMING_FAKE_BATTERY", "90")),
                     drain=float(os.environ.get("HOMING_FAKE_DRAIN", "0")))


class Scripted(py_trees.behaviour.Behaviour):
    """Plays ``script`` (one status per tick over its whole life, the last one repeated); counts ticks, starts, halts."""

    def __init__(self, name: str, script: list[Status]):
        super().__init__(name=name)
        self.script = list(script)
        self.i = 0
        self.ticks = 0
        self.starts = 0
        self.halts = 0

    def initialise(self) -> None:
        self.starts += 1

    def update(self) -> Status:
        self.ticks += 1
        status = self.script[min(self.i, len(self.script) - 1)]
        self.i += 1
        return status

    def terminate(self, new_status: Status) -> None:
        if new_status == Status.INVALID and self.status == Status.RUNNING:
            self.halts += 1


def after(k: int, final: Status = S) -> list[Status]:
    """RUNNING for k - 1 ticks, then ``final`` (so it finishes on its k-th tick)."""
    return [R] * (k - 1) + [final]


def tick(root: Any, robot: FakeRobot | None = None, dt: float = 0.1) -> Status:
    """One tick of ``root``; advance the fake clock by ``dt`` afterwards."""
    root.tick_once()
    if robot is not None:
        robot.clock.t = round(robot.clock.t + dt, 9)
    return root.status


def make_robot_interrupted(seed: int = 0) -> FakeRobot:
    """A factory that is stopped half-way, as if Ctrl-C (or ``$HOMING_FAKE_SIGNAL``) arrived during start-up."""
    import signal

    os.kill(os.getpid(), getattr(signal, os.environ.get("HOMING_FAKE_SIGNAL", "SIGINT")))
    return FakeRobot(seed=seed)


NOT_A_FACTORY = 42  # ``--adapter tests.mission_fakes:NOT_A_FACTORY``


def make_nothing(seed: int = 0) -> str:
    """A factory that returns something that is not a robot."""
    return f"robot {seed}"


def make_robot_failing(seed: int = 0) -> FakeRobot:
    raise RuntimeError("the serial port /dev/ttyUSB0 is busy")


def board(*keys: str) -> py_trees.blackboard.Client:
    """A fresh blackboard (every entry cleared) and a client that may write ``keys``."""
    py_trees.blackboard.Blackboard.storage.clear()
    client = py_trees.blackboard.Client(name="test-board")
    for key in keys:
        client.register_key(key=key, access=py_trees.common.Access.WRITE)
    return client

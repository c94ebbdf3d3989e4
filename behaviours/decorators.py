"""Control nodes of the mission language: composites and decorators, on the adapter's clock.

The names of the field collide (DESIGN.md, "The mission language"), so each
node says exactly what it does against BehaviorTree.CPP (BT.CPP), py_trees
and Nav2. py_trees' own classes are used where their semantics are the ones
documented here (sequence, fallback, retry, repeat, inverter, force-success,
force-failure, one-shot); homing's own where they are not: timeout (py_trees
uses the wall clock, homing the adapter's), rate limit, guard with a
condition subtree, parallel with an N-of-M policy, Nav2's RecoveryNode and
RoundRobin.

A status change within one tick is the only kind of retry here that does not
cost a tick: ``recovery`` and ``round_robin`` re-tick children in the same
tick, as Nav2 does; ``retry`` and ``repeat`` start the next attempt on the
next tick, as py_trees does (so a child that fails at once can never spin a
tick forever).
"""

from __future__ import annotations

import math
from collections.abc import Iterator
from collections.abc import Sequence as Seq
from typing import Any

import py_trees
from homing.behaviours.registry import REQUIRED, Param, register
from py_trees.behaviour import Behaviour
from py_trees.common import OneShotPolicy, Status
from py_trees.composites import Composite

_CHILDREN = ("children",)


class _Clock:
    """Mixin: the adapter's clock from ``setup(robot=...)`` (never the wall clock)."""

    robot: Any = None

    def setup(self, **kwargs: Any) -> None:
        self.robot = kwargs.get("robot", self.robot)

    def now(self) -> float:
        if self.robot is None:
            raise RuntimeError(f"{type(self).__name__} needs tree.setup(robot=adapter) for its clock")
        return float(self.robot.clock.now())


# --------------------------------------------------------------------------- composites


@register("sequence", kind="composite", params=(Param("memory", bool, True, doc="resume at the running child"),))
class Sequence(py_trees.composites.Sequence):
    """Tick children in order until one fails or runs; SUCCESS when all succeed.

    ``memory: true`` (the default) is py_trees ``Sequence(memory=True)`` and
    BT.CPP's ``Sequence``: while RUNNING, the next tick resumes at the running
    child without re-ticking the ones that already succeeded; after a FAILURE
    it starts again from the first child (BT.CPP's ``SequenceWithMemory``
    would not). ``memory: false`` is ``reactive_sequence``.
    """

    def __init__(self, name: str, children: Seq[Behaviour], memory: bool = True):
        super().__init__(name=name, memory=memory, children=list(children))


@register("reactive_sequence", kind="composite")
class ReactiveSequence(py_trees.composites.Sequence):
    """Re-tick every child from the first on every tick; a failing earlier child halts a running later one.

    py_trees ``Sequence(memory=False)``, BT.CPP ``ReactiveSequence``. Use it
    for conditions that must hold all along (battery above x, then explore).
    """

    def __init__(self, name: str, children: Seq[Behaviour]):
        super().__init__(name=name, memory=False, children=list(children))


@register("fallback", kind="composite", params=(Param("memory", bool, True, doc="resume at the running child"),))
class Fallback(py_trees.composites.Selector):
    """Tick children in order until one succeeds or runs; FAILURE when all fail (a.k.a. selector).

    ``memory: true`` (default) is py_trees ``Selector(memory=True)`` and
    BT.CPP's ``Fallback``: a running child keeps the turn, higher-priority
    children are not re-checked until it finishes. ``memory: false`` is
    ``reactive_fallback``.
    """

    def __init__(self, name: str, children: Seq[Behaviour], memory: bool = True):
        super().__init__(name=name, memory=memory, children=list(children))


@register("reactive_fallback", kind="composite")
class ReactiveFallback(py_trees.composites.Selector):
    """Re-check higher priorities every tick; one that succeeds or runs halts the lower running child.

    py_trees ``Selector(memory=False)``, BT.CPP ``ReactiveFallback``: the
    priority-interrupt pattern (the battery guard preempting exploration).
    """

    def __init__(self, name: str, children: Seq[Behaviour]):
        super().__init__(name=name, memory=False, children=list(children))


register("selector", kind="composite", params=(Param("memory", bool, True, doc="resume at the running child"),))(
    Fallback
)
register("reactive_selector", kind="composite")(ReactiveFallback)


@register(
    "parallel",
    kind="composite",
    params=(
        Param("success", (str, int), "all", doc="'all', 'one' or N: how many children must succeed", minimum=1),
    ),
)
class Parallel(Composite):
    """Tick every child each tick; SUCCESS once N have succeeded, FAILURE once N can no longer succeed.

    ``success: all`` (default) = py_trees ``SuccessOnAll`` (synchronised) and
    BT.CPP ``ParallelNode`` with ``success_count = M``: any failure fails it.
    ``success: one`` = one success is enough, and it fails only when every
    child has failed (py_trees' ``SuccessOnOne`` fails on the first failure;
    BT.CPP's ``failure_count = M`` does what homing does). A child that has
    finished is not ticked again until the parallel restarts; still-running
    children are halted when the parallel finishes.
    """

    def __init__(self, name: str, children: Seq[Behaviour], success: str | int = "all"):
        super().__init__(name=name, children=list(children))
        n = len(self.children)
        if success == "all":
            self.needed = n
        elif success == "one":
            self.needed = min(1, n)
        elif isinstance(success, int) and not isinstance(success, bool) and 1 <= success <= max(n, 1):
            self.needed = success
        else:
            raise ValueError(f"success must be 'all', 'one' or an integer 1..{n} (the number of children), not {success!r}")

    def tick(self) -> Iterator[Behaviour]:
        if self.status != Status.RUNNING:
            for child in self.children:
                if child.status != Status.INVALID:
                    child.stop(Status.INVALID)
            self.initialise()
        for child in self.children:
            if child.status in (Status.SUCCESS, Status.FAILURE):
                continue
            self.current_child = child
            yield from child.tick()
        successes = sum(c.status == Status.SUCCESS for c in self.children)
        failures = sum(c.status == Status.FAILURE for c in self.children)
        self.feedback_message = f"{successes}/{self.needed} succeeded, {failures} failed"
        if successes >= self.needed:
            self.stop(Status.SUCCESS)
        elif len(self.children) - failures < self.needed:
            self.stop(Status.FAILURE)
        else:
            self.status = Status.RUNNING
        yield self

    def stop(self, new_status: Status = Status.INVALID) -> None:
        for child in self.children:
            if child.status == Status.RUNNING:
                child.stop(Status.INVALID)
        super().stop(new_status)


@register("round_robin", kind="composite")
class RoundRobin(Composite):
    """Try children in turn, starting after the one that last finished: Nav2's ``RoundRobin``.

    A tick runs the current child; FAILURE moves on to the next child in the
    same tick (wrapping round), SUCCESS returns SUCCESS, RUNNING returns
    RUNNING. FAILURE only when every child has failed in a row. The turn is
    kept across activations, so under a ``recovery`` node each recovery
    attempt uses the next action (clear costmap, then spin, then back up, …).
    As in Nav2, a halt (preemption while running) resets the turn to the first child.
    """

    def __init__(self, name: str, children: Seq[Behaviour]):
        super().__init__(name=name, children=list(children))
        self.index = 0
        self.failed = 0

    def tick(self) -> Iterator[Behaviour]:
        if self.status != Status.RUNNING:
            self.failed = 0
            self.initialise()
        n = len(self.children)
        while n and self.failed < n:
            child = self.children[self.index]
            self.current_child = child
            yield from child.tick()
            if child.status != Status.RUNNING:
                self.index = (self.index + 1) % n
            if child.status == Status.SUCCESS:
                self.failed = 0
                self.stop(Status.SUCCESS)
                yield self
                return
            if child.status == Status.RUNNING:
                self.status = Status.RUNNING
                yield self
                return
            self.failed += 1
        self.failed = 0
        self.stop(Status.FAILURE)
        yield self

    def stop(self, new_status: Status = Status.INVALID) -> None:
        if new_status == Status.INVALID and self.status == Status.RUNNING:
            self.index = 0
            self.failed = 0
        super().stop(new_status)


@register(
    "recovery",
    kind="decorator",
    slots=("child", "recovery"),
    params=(Param("retries", int, 1, doc="recovery rounds after the first attempt (Nav2 number_of_retries)", minimum=0),),
)
class RecoveryNode(Composite):
    """Run ``child``; on failure run ``recovery`` and try ``child`` again, up to ``retries`` times: Nav2's ``RecoveryNode``.

    ``retries: 6`` means one attempt and six retries (seven attempts of the
    child at most), exactly Nav2's ``number_of_retries``. Each retry needs the
    recovery branch to SUCCEED first; a failing recovery fails the node. Like
    Nav2 it switches branches within the same tick. The count resets when
    the node finishes or is halted.
    """

    def __init__(self, name: str, child: Behaviour, recovery: Behaviour, retries: int = 1):
        if retries < 0:
            raise ValueError(f"retries must be ≥ 0, not {retries}")
        super().__init__(name=name, children=[child, recovery])
        self.retries = retries
        self.used = 0
        self.branch = 0

    def tick(self) -> Iterator[Behaviour]:
        if self.status != Status.RUNNING:
            self.used = 0
            self.branch = 0
            for child in self.children:
                if child.status != Status.INVALID:
                    child.stop(Status.INVALID)
            self.initialise()
        while True:
            child = self.children[self.branch]
            self.current_child = child
            yield from child.tick()
            self.feedback_message = f"retries used {self.used} of {self.retries}"
            if child.status == Status.RUNNING:
                self.status = Status.RUNNING
                yield self
                return
            if self.branch == 0:
                if child.status == Status.FAILURE and self.used < self.retries:
                    self.branch = 1
                    continue
                self.stop(child.status)
                yield self
                return
            if child.status == Status.SUCCESS:
                self.used += 1
                self.branch = 0
                continue
            self.stop(Status.FAILURE)
            yield self
            return


@register("guard", kind="decorator", slots=("condition", "child"))
class Guard(Composite):
    """Re-check ``condition`` before every tick of ``child``; halt the child the moment it is false.

    Each tick the condition subtree is ticked first: SUCCESS → the child is
    ticked and the guard returns its status; anything else (FAILURE, or
    RUNNING, which counts as "not yet true") → a running child is halted
    and the guard returns FAILURE. py_trees' ``EternalGuard`` with a
    condition node instead of a function; BT.CPP's ``_while`` precondition.
    """

    def __init__(self, name: str, condition: Behaviour, child: Behaviour):
        super().__init__(name=name, children=[condition, child])

    def tick(self) -> Iterator[Behaviour]:
        if self.status != Status.RUNNING:
            self.initialise()
        condition, child = self.children
        self.current_child = condition
        yield from condition.tick()
        if condition.status == Status.SUCCESS:
            self.current_child = child
            yield from child.tick()
            if child.status == Status.RUNNING:
                self.status = Status.RUNNING
            else:
                self.stop(child.status)
        else:
            if child.status == Status.RUNNING:
                child.stop(Status.INVALID)
            self.feedback_message = f"guard '{condition.name}' is false"
            self.stop(Status.FAILURE)
        yield self


# --------------------------------------------------------------------------- decorators


@register(
    "retry",
    kind="decorator",
    params=(Param("attempts", int, REQUIRED, doc="attempts of the child in all (≥ 1)", minimum=1),),
)
class Retry(py_trees.decorators.Retry):
    """Run the child up to ``attempts`` times until it succeeds; FAILURE on the last failure.

    ``attempts: 3`` = three attempts in all = py_trees ``Retry(num_failures=3)``
    = BT.CPP ``RetryUntilSuccessful(num_attempts=3)`` = Nav2
    ``RecoveryNode(number_of_retries=2)`` without a recovery branch. A failed
    attempt returns RUNNING for that tick and the child starts afresh on the
    next one. Resets when the decorator restarts.
    """

    def __init__(self, name: str, child: Behaviour, attempts: int):
        if attempts < 1:
            raise ValueError(f"attempts must be ≥ 1, not {attempts}")
        super().__init__(name=name, child=child, num_failures=attempts)


@register(
    "timeout",
    kind="decorator",
    params=(Param("seconds", float, REQUIRED, "s", "fail the child after this long on the adapter clock", above=0.0),),
)
class Timeout(_Clock, py_trees.decorators.Decorator):
    """FAILURE and halt the child if it is still running ``seconds`` after the decorator started.

    Seconds on the adapter's clock (py_trees' ``Timeout`` uses the wall
    clock; BT.CPP's ``Timeout`` counts *milliseconds*, ``msec``). The
    deadline is checked before the child is ticked, so a child started at
    t = 0 under ``seconds: 1`` ticked at 10 Hz gets the ticks at 0.0 … 0.9
    and the decorator fails at t = 1.0 without ticking it again.
    """

    def __init__(self, name: str, child: Behaviour, seconds: float):
        if not seconds > 0:
            raise ValueError(f"seconds must be > 0, not {seconds}")
        super().__init__(name=name, child=child)
        self.seconds = float(seconds)  # [s]
        self.deadline = math.inf  # [s] adapter clock

    def initialise(self) -> None:
        self.deadline = self.now() + self.seconds
        self.feedback_message = ""

    def tick(self) -> Iterator[Behaviour]:
        if self.status == Status.RUNNING and self.now() >= self.deadline:
            self.feedback_message = f"timed out after {self.seconds:g} s"
            self.stop(Status.FAILURE)
            yield self
            return
        yield from super().tick()

    def update(self) -> Status:
        if self.decorated.status == Status.RUNNING:
            self.feedback_message = f"{self.deadline - self.now():.1f} s left"
        return self.decorated.status


@register(
    "repeat",
    kind="decorator",
    params=(Param("times", int, -1, doc="successes to reach; -1 = forever", minimum=-1),),
)
class Repeat(py_trees.decorators.Repeat):
    """Run the child again after each success until it has succeeded ``times`` times (-1 forever).

    py_trees ``Repeat(num_success)``, BT.CPP ``Repeat(num_cycles)``. A
    failure of the child fails the decorator at once. Each new cycle starts
    on the next tick.
    """

    def __init__(self, name: str, child: Behaviour, times: int = -1):
        if times == 0 or times < -1:
            raise ValueError(f"times must be ≥ 1 or -1 (forever), not {times}")
        super().__init__(name=name, child=child, num_success=times)


@register("inverter", kind="decorator")
class Inverter(py_trees.decorators.Inverter):
    """SUCCESS ↔ FAILURE; RUNNING stays RUNNING (py_trees ``Inverter``, BT.CPP ``Inverter``)."""

    def __init__(self, name: str, child: Behaviour):
        super().__init__(name=name, child=child)


@register("force_success", kind="decorator")
class ForceSuccess(py_trees.decorators.FailureIsSuccess):
    """FAILURE becomes SUCCESS; RUNNING stays RUNNING (BT.CPP ``ForceSuccess``, py_trees ``FailureIsSuccess``)."""

    def __init__(self, name: str, child: Behaviour):
        super().__init__(name=name, child=child)


@register("force_failure", kind="decorator")
class ForceFailure(py_trees.decorators.SuccessIsFailure):
    """SUCCESS becomes FAILURE; RUNNING stays RUNNING (BT.CPP ``ForceFailure``, py_trees ``SuccessIsFailure``)."""

    def __init__(self, name: str, child: Behaviour):
        super().__init__(name=name, child=child)


@register(
    "one_shot",
    kind="decorator",
    params=(
        Param(
            "policy",
            str,
            "on_completion",
            doc="on_completion: run once whatever the outcome; on_success: until it succeeds once",
            choices=("on_completion", "on_success"),
        ),
    ),
)
class OneShot(py_trees.decorators.OneShot):
    """Run the child to completion once per run, then return that final status without ticking it.

    ``on_completion`` (default) is BT.CPP ``RunOnce``; ``on_success`` lets a
    failure be retried until the child succeeds once (py_trees'
    ``oneshot`` idiom default).
    """

    def __init__(self, name: str, child: Behaviour, policy: str = "on_completion"):
        policies = {"on_completion": OneShotPolicy.ON_COMPLETION, "on_success": OneShotPolicy.ON_SUCCESSFUL_COMPLETION}
        if policy not in policies:
            raise ValueError(f"policy must be one of {sorted(policies)}, not {policy!r}")
        super().__init__(name=name, child=child, policy=policies[policy])


@register(
    "rate_limit",
    kind="decorator",
    params=(Param("hz", float, REQUIRED, "Hz", "start the child at most this often (adapter clock)", above=0.0),),
)
class RateLimit(_Clock, py_trees.decorators.Decorator):
    """Start the child at most ``hz`` times a second; in between, return its last final status.

    A running child is ticked every tick (as Nav2's ``RateController``). Once
    it has finished, ticks within ``1/hz`` seconds of its last start return
    that same SUCCESS or FAILURE without ticking it. Nav2 returns RUNNING in
    between, which suits its ``PipelineSequence``; py_trees has none, and a
    cached status keeps a ``reactive_sequence`` [rate_limit(plan), follow]
    following between replans. A halted child is started again at once.
    """

    def __init__(self, name: str, child: Behaviour, hz: float):
        if not hz > 0:
            raise ValueError(f"hz must be > 0, not {hz}")
        super().__init__(name=name, child=child)
        self.period = 1.0 / float(hz)  # [s]
        self.last_start = -math.inf  # [s] adapter clock
        self.last_status: Status | None = None

    def tick(self) -> Iterator[Behaviour]:
        now = self.now()
        if self.decorated.status != Status.RUNNING:
            if self.last_status is not None and now - self.last_start < self.period:
                self.feedback_message = f"next start in {self.period - (now - self.last_start):.2f} s"
                self.status = self.last_status
                yield self
                return
            self.last_start = now
        yield from super().tick()

    def update(self) -> Status:
        status = self.decorated.status
        self.last_status = status if status in (Status.SUCCESS, Status.FAILURE) else None
        return status

    def terminate(self, new_status: Status) -> None:
        if new_status == Status.INVALID and self.status == Status.RUNNING:
            self.last_status = None


def control_nodes() -> tuple[str, ...]:
    """Names of the control nodes defined here (composites and decorators)."""
    return (
        "sequence", "reactive_sequence", "fallback", "reactive_fallback", "selector", "reactive_selector",
        "parallel", "round_robin", "recovery", "guard", "retry", "timeout", "repeat", "inverter",
        "force_success", "force_failure", "one_shot", "rate_limit",
    )  # fmt: skip

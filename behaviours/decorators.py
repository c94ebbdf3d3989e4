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


class _PassesOverSkipped(py_trees.composites.Sequence):
    """py_trees' ``Sequence`` that passes over a child left INVALID by its tick (BT.CPP's SKIPPED).

    A node that decides not to run this tick (``run_once`` after its run)
    reports INVALID, "not ticked"; as in BT.CPP, a sequence goes on to the
    next child instead of stopping there, and a sequence whose children were
    all skipped is skipped itself. Everything else is py_trees' own tick.
    """

    def tick(self) -> Iterator[Behaviour]:
        first = 0
        if self.status != Status.RUNNING:
            self.current_child = self.children[0] if self.children else None
            for child in self.children:
                if child.status != Status.INVALID:
                    child.stop(Status.INVALID)
            self.initialise()
        elif self.memory and self.current_child is not None:
            first = self.children.index(self.current_child)
        else:
            self.current_child = self.children[0] if self.children else None
        skipped = 0
        for index, child in enumerate(self.children[first:], start=first):
            self.current_child = child
            for node in child.tick():
                yield node
                if node is child and node.status in (Status.RUNNING, Status.FAILURE):
                    if not self.memory:
                        for later in self.children[index + 1:]:
                            if later.status != Status.INVALID:
                                later.stop(Status.INVALID)
                    if node.status == Status.FAILURE:
                        self.stop(Status.FAILURE)
                    else:
                        self.status = Status.RUNNING
                    yield self
                    return
            skipped += child.status == Status.INVALID
        if self.children and skipped == len(self.children):
            self.stop(Status.INVALID)
            self.feedback_message = "every child skipped"
        else:
            self.stop(Status.SUCCESS)
        yield self


@register("sequence", kind="composite", params=(Param("memory", bool, True, doc="resume at the running child"),))
class Sequence(_PassesOverSkipped):
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
class ReactiveSequence(_PassesOverSkipped):
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
        Param("failure", (str, int), "auto", doc="'auto' (once success is out of reach), 'all' or N failures that fail it",
              minimum=1),
    ),
)
class Parallel(Composite):
    """Tick every child each tick; SUCCESS once N have succeeded, FAILURE once N can no longer succeed.

    ``success: all`` (default) = py_trees ``SuccessOnAll`` (synchronised) and
    BT.CPP ``ParallelNode`` with ``success_count = M``: any failure fails it.
    ``success: one`` = one success is enough, and it fails only when every
    child has failed (py_trees' ``SuccessOnOne`` fails on the first failure:
    add ``failure: 1``; BT.CPP's ``failure_count = M`` does what homing does).
    ``failure: N`` also fails it after N failures, as BT.CPP's
    ``failure_count`` (it fails too once success is out of reach). A child
    that has finished is not ticked again until the parallel restarts;
    still-running children are halted when the parallel finishes. A child
    that skips itself (``run_once`` after its run) counts as neither.
    """

    def __init__(self, name: str, children: Seq[Behaviour], success: str | int = "all", failure: str | int = "auto"):
        super().__init__(name=name, children=list(children))
        n = len(self.children)
        self.needed = self._count("success", success, n, {"all": n, "one": min(1, n)})
        self.failures_allowed = self._count("failure", failure, n, {"all": n, "auto": n + 1})

    @staticmethod
    def _count(what: str, value: str | int, n: int, words: dict[str, int]) -> int:
        if isinstance(value, str) and value in words:
            return words[value]
        if isinstance(value, int) and not isinstance(value, bool) and 1 <= value <= max(n, 1):
            return value
        spelt = ", ".join(f"'{w}'" for w in words)
        raise ValueError(f"{what} must be {spelt} or an integer 1..{n} (the number of children), not {value!r}")

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
        skipped = sum(c.status == Status.INVALID for c in self.children)
        self.feedback_message = f"{successes}/{self.needed} succeeded, {failures} failed"
        if successes >= min(self.needed, len(self.children) - skipped) and successes:
            self.stop(Status.SUCCESS)
        elif len(self.children) - failures - skipped < self.needed or failures >= self.failures_allowed:
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
    kept across activations that succeed, so under a ``recovery`` node each
    recovery attempt uses the next action (clear costmap, then spin, then
    back up, …). As in Nav2, a halt (preemption while running) and a whole
    round of failures both reset the turn to the first child.
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
        # A whole round failed: Nav2 halts the node, so the next activation starts at the first child.
        self.index = 0
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
    Whenever the guard finishes, whatever is still RUNNING below it (a
    condition subtree that had not decided) is halted, so the next
    activation starts the condition afresh (BT.CPP ``resetChildren``).
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
            self.feedback_message = f"guard '{condition.name}' is false"
            self.stop(Status.FAILURE)
        yield self

    def stop(self, new_status: Status = Status.INVALID) -> None:
        for node in self.children:
            if node.status == Status.RUNNING:
                node.stop(Status.INVALID)
        super().stop(new_status)


# --------------------------------------------------------------------------- decorators


@register(
    "retry",
    kind="decorator",
    params=(Param("attempts", int, REQUIRED, doc="attempts of the child in all (≥ 1; -1 = until it succeeds)",
                  minimum=-1),),
)
class Retry(py_trees.decorators.Retry):
    """Run the child up to ``attempts`` times until it succeeds; FAILURE on the last failure.

    ``attempts: 3`` = three attempts in all = py_trees ``Retry(num_failures=3)``
    = BT.CPP ``RetryUntilSuccessful(num_attempts=3)`` = Nav2
    ``RecoveryNode(number_of_retries=2)`` without a recovery branch;
    ``attempts: -1`` retries until it succeeds (BT.CPP's -1). A failed
    attempt returns RUNNING for that tick and the child starts afresh on the
    next one (BT.CPP retries within the same tick). Resets when the
    decorator restarts.
    """

    PORT_PARAMS = ("attempts",)

    def __init__(self, name: str, child: Behaviour, attempts: int):
        super().__init__(name=name, child=child, num_failures=1)
        self.set_port("attempts", attempts)

    def set_port(self, name: str, value: int) -> None:
        if value < 1 and value != -1:
            raise ValueError(f"attempts must be ≥ 1 or -1 (until it succeeds), not {value}")
        self.num_failures = math.inf if value == -1 else value  # type: ignore[assignment]


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

    PORT_PARAMS = ("times",)

    def __init__(self, name: str, child: Behaviour, times: int = -1):
        super().__init__(name=name, child=child, num_success=-1)
        self.set_port("times", times)

    def set_port(self, name: str, value: int) -> None:
        if value == 0 or value < -1:
            raise ValueError(f"times must be ≥ 1 or -1 (forever), not {value}")
        self.num_success = value


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

    PORT_PARAMS = ("hz",)

    def set_port(self, name: str, value: float) -> None:
        if not value > 0:
            raise ValueError(f"hz must be > 0, not {value}")
        self.period = 1.0 / float(value)

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

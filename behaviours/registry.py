"""The node registry: every leaf and decorator a mission may name, with its declarations.

A node declares what the mission compiler needs to check a mission before the
first tick (STYLE.md, rule 4): its parameters (type, default, unit, doc) and
the blackboard keys it reads and writes. Leaves register with
:func:`register`; third-party packages add theirs through the entry-point
group ``homing.behaviours`` (each entry point names a module to import, whose
import registers its nodes, or a callable that is called with no arguments).

Services (:class:`Service`) are the other half: the always-on world model
that the runner updates every tick before the tree (odometry → scan-matched
grid, tags → landmark SLAM), like the ROS nodes that run beside a Nav2 tree.
They declare the keys they write too, so that a leaf reading ``/map/grid``
checks against the mission's services.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any, Protocol, TypeVar

import py_trees
from homing.robot import Observation, RobotAdapter


class _Required:
    def __repr__(self) -> str:
        return "REQUIRED"


REQUIRED: Any = _Required()


@dataclass(frozen=True)
class Param:
    """One parameter of a node: name, Python type(s), default (or REQUIRED), unit and doc.

    ``type`` is ``float``, ``int``, ``bool``, ``str``, ``list`` or a tuple of
    them; ``choices`` restricts a string to a set (e.g. plugin names).
    A number must lie in ``[minimum, maximum]`` (in ``unit``) and above
    ``above`` when they are given — a negative distance or a zero speed is
    a mistake, not something to run — and must be finite (NaN is accepted
    only where the default is NaN, which then means "not given").
    """

    name: str
    type: type | tuple[type, ...]
    default: Any = REQUIRED
    unit: str = ""
    doc: str = ""
    choices: tuple[str, ...] = ()
    minimum: float | None = None
    maximum: float | None = None
    above: float | None = None  # exclusive minimum

    @property
    def required(self) -> bool:
        return self.default is REQUIRED


@dataclass(frozen=True)
class NodeSpec:
    """What the registry knows of a node kind.

    ``kind`` is ``"action"``, ``"condition"``, ``"decorator"`` or
    ``"composite"``. ``factory(name=..., **params)`` builds the py_trees
    behaviour (decorators and composites also get ``child``/``children``).

    ``slots`` names the children a control node takes, each passed to the
    factory as a keyword: ``("child",)`` for a decorator (the default when
    empty), ``("children",)`` for a composite's list, or named branches such
    as ``("child", "recovery")``; the names in ``optional`` may be left out
    (the factory then gets ``None`` for them, e.g. the ``else`` branch of
    ``if_then_else``). A key in ``reads``/``writes`` that starts
    with ``$`` names a parameter whose value is the key (e.g. ``"$key"`` for
    a blackboard leaf whose ``key`` parameter says which entry it sets).
    """

    name: str
    kind: str
    factory: Callable[..., py_trees.behaviour.Behaviour]
    params: tuple[Param, ...] = ()
    reads: tuple[str, ...] = ()
    writes: tuple[str, ...] = ()
    doc: str = ""
    source: str = "homing"
    slots: tuple[str, ...] = ()
    optional: tuple[str, ...] = ()

    def param(self, name: str) -> Param | None:
        return next((p for p in self.params if p.name == name), None)

    @property
    def child_slots(self) -> tuple[str, ...]:
        """The keyword(s) the factory takes children by (empty for a leaf)."""
        if self.slots:
            return self.slots
        return {"decorator": ("child",), "composite": ("children",)}.get(self.kind, ())

    def keys(self, params: dict[str, Any]) -> tuple[tuple[str, ...], tuple[str, ...]]:
        """(reads, writes) with ``$param`` entries replaced by the parameter's value."""

        def resolve(keys: tuple[str, ...]) -> tuple[str, ...]:
            out = []
            for key in keys:
                if key.startswith("$"):
                    value = params.get(key[1:])
                    if isinstance(value, str) and value:
                        out.append(value)
                else:
                    out.append(key)
            return tuple(out)

        return resolve(self.reads), resolve(self.writes)


NODES: dict[str, NodeSpec] = {}

B = TypeVar("B", bound=type)


def register(
    name: str | None = None,
    *,
    kind: str = "action",
    params: tuple[Param, ...] | None = None,
    reads: tuple[str, ...] | None = None,
    writes: tuple[str, ...] | None = None,
    slots: tuple[str, ...] = (),
    optional: tuple[str, ...] = (),
) -> Callable[[B], B]:
    """Class decorator: register a behaviour class as a mission node.

    Declarations default to the class attributes ``PARAMS``, ``READS`` and
    ``WRITES``; the doc is the class docstring's first paragraph. ``slots``
    and ``optional``: see :class:`NodeSpec` (only control nodes need them).
    """

    def wrap(cls: B) -> B:
        node = name or cls.__name__
        doc = (cls.__doc__ or "").strip().split("\n\n")[0].replace("\n", " ")
        spec = NodeSpec(
            name=node,
            kind=kind,
            factory=cls,
            params=tuple(params if params is not None else getattr(cls, "PARAMS", ())),
            reads=tuple(reads if reads is not None else getattr(cls, "READS", ())),
            writes=tuple(writes if writes is not None else getattr(cls, "WRITES", ())),
            doc=doc,
            source=cls.__module__,
            slots=tuple(slots),
            optional=tuple(optional),
        )
        if node in NODES and NODES[node].factory is not cls:
            raise ValueError(f"node '{node}' registered twice ({NODES[node].source} and {spec.source})")
        NODES[node] = spec
        return cls

    return wrap


class Service(Protocol):
    """An always-on part of the world model, updated by the runner every tick before the tree.

    ``setup`` gets the adapter and the blackboard client to write through;
    ``update`` must not block (it runs inside the tick budget).
    """

    name: str
    writes: tuple[str, ...]

    def setup(self, robot: RobotAdapter, blackboard: py_trees.blackboard.Client) -> None: ...

    def update(self, obs: Observation) -> None: ...

    def shutdown(self) -> None: ...


@dataclass(frozen=True)
class ServiceSpec:
    """A service kind: its factory (``factory(**params)``), parameters and written keys."""

    name: str
    factory: Callable[..., Service]
    params: tuple[Param, ...] = ()
    writes: tuple[str, ...] = ()
    doc: str = ""
    requires: tuple[str, ...] = field(default_factory=tuple)


SERVICES: dict[str, ServiceSpec] = {}


def register_service(
    name: str, *, params: tuple[Param, ...] = (), writes: tuple[str, ...] = (), requires: tuple[str, ...] = ()
) -> Callable[[B], B]:
    """Class decorator: register a service kind by name (``requires``: services it reads from)."""

    def wrap(cls: B) -> B:
        doc = (cls.__doc__ or "").strip().split("\n\n")[0].replace("\n", " ")
        SERVICES[name] = ServiceSpec(name, cls, tuple(params), tuple(writes), doc, tuple(requires))
        return cls

    return wrap

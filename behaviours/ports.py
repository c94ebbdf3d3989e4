"""Blackboard ports: a node parameter read from the blackboard when the node starts, not fixed when the tree is built.

In a mission, a parameter written ``"{key}"`` (BT.CPP's spelling; unquoted
``{key}`` is the same thing to YAML) names a blackboard entry instead of a
value: ``Wait: {seconds: "{patience}"}`` waits as long as ``/patience`` says
when the ``Wait`` starts. Keys are resolved by the compiler (see
:func:`parse_port` and :mod:`homing.missions.compiler`): ``{/nav/goal}`` is
absolute, ``{@goal}`` is the root blackboard's ``/goal``, ``{=}`` is the
entry named like the parameter, and a bare ``{goal}`` is ``/goal`` at the
top of a mission and the subtree's own entry (or what the caller remapped
it to) inside a subtree, as BT.CPP's isolated subtree blackboards.

At run time a node with ports is an instance of :func:`ported` (its class
with :class:`PortBinding` in front): on every start of the node (a tick
while it is not RUNNING) the ports are read, checked against the
parameter's type and unit like a YAML value (a bare number is in the
parameter's unit), and handed to the node with ``set_port(name, value)``
for the names its class lists in ``PORT_PARAMS``, else set as the attribute
of that name (homing's leaves keep each parameter under its own name). A port that is
unset or holds a wrong value fails the node with a feedback message saying
which (BT.CPP throws; a FAILURE lets a recovery branch act).
"""

from __future__ import annotations

import re
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from typing import Any, cast

import py_trees
from homing.behaviours.registry import Param
from py_trees.behaviour import Behaviour
from py_trees.common import Access, Status

# {key}, {/abs/key}, {@root_key}, {=}: what BT.CPP accepts between the braces, plus homing's absolute keys.
KEY_TEXT = r"(?:@?/?[A-Za-z_][A-Za-z0-9_.\-]*(?:/[A-Za-z_][A-Za-z0-9_.\-]*)*|=)"
PORT_PATTERN = re.compile(r"^\{\s*(" + KEY_TEXT + r")\s*\}$")
KEY_PATTERN = re.compile(r"^" + KEY_TEXT + r"$")


@dataclass(frozen=True)
class PortRef:
    """A ``{key}`` in a mission, before the compiler resolves it: the text between the braces."""

    text: str


@dataclass(frozen=True)
class Port:
    """A resolved port: the absolute blackboard key a parameter is read from."""

    key: str

    def __str__(self) -> str:
        return "{" + self.key + "}"


def parse_port(value: Any) -> PortRef | None:
    """The port a YAML value names, or None: ``"{goal}"``, or the one-entry mapping ``{goal: null}`` YAML makes of ``{goal}``."""
    if isinstance(value, str):
        m = PORT_PATTERN.match(value.strip())
        return PortRef(m.group(1)) if m else None
    if isinstance(value, dict) and len(value) == 1:
        key, inner = next(iter(value.items()))
        if inner is None and isinstance(key, str) and KEY_PATTERN.match(key):
            return PortRef(key)
    return None


def placeholder(param: Param) -> Any:
    """A value to build a node with while its parameter waits for its port: the default, or a neutral value."""
    if not param.required:
        return param.default
    types = param.type if isinstance(param.type, tuple) else (param.type,)
    if float in types or int in types:
        return 1
    if bool in types:
        return False
    if str in types:
        return param.choices[0] if param.choices else ""
    return []


class PortBinding:
    """Mixin put in front of a node's class by :func:`ported`: reads the node's ports each time it starts."""

    ports: dict[str, tuple[Port, Param]]
    PORT_PARAMS: tuple[str, ...] = ()  # parameters a class takes through set_port(name, value)

    def attach_ports(self, ports: dict[str, tuple[Port, Param]], convert: Callable[[Param, Any], Any]) -> None:
        """Set the ports (parameter name → port and declaration) and get read access to their keys.

        ``convert(param, raw)`` checks a value read from the blackboard as the
        compiler checks one written in YAML (raises ValueError).
        """
        self.ports = dict(ports)
        self._convert = convert
        self._port_bb = py_trees.blackboard.Client(name=f"{getattr(self, 'name', 'node')}:ports")
        for port, _ in self.ports.values():
            self._port_bb.register_key(key=port.key, access=Access.READ)

    def bind_ports(self) -> str | None:
        """Read every port into the node; the first problem as a message, or None."""
        missing = object()
        for name, (port, param) in self.ports.items():
            try:
                raw = self._port_bb.get(port.key)
            except KeyError:
                raw = missing
            if raw is missing:
                return f"port {name}={port}: {port.key} is not set"
            try:
                value = self._convert(param, raw)
                if name in self.PORT_PARAMS:
                    cast(Any, self).set_port(name, value)
                else:
                    setattr(self, name, value)
            except (ValueError, TypeError) as err:
                return f"port {name}={port}: {err}"
        return None

    def tick(self) -> Iterator[Behaviour]:
        node: Any = self
        if node.status != Status.RUNNING:
            problem = self.bind_ports()
            if problem is not None:
                node.feedback_message = problem
                node.stop(Status.FAILURE)
                yield node
                return
        yield from super().tick()  # type: ignore[misc]


_PORTED: dict[type, type] = {}


def ported(cls: type) -> type:
    """``cls`` with :class:`PortBinding` in front (one class per node class, same name)."""
    if cls not in _PORTED:
        _PORTED[cls] = type(cls.__name__, (PortBinding, cls), {"__module__": cls.__module__, "__doc__": cls.__doc__})
    return _PORTED[cls]


def accepts_port(node: Behaviour, name: str) -> bool:
    """Whether a built node can take parameter ``name`` from a port (listed in ``PORT_PARAMS`` or an attribute)."""
    return name in getattr(node, "PORT_PARAMS", ()) or (name != "name" and hasattr(node, name))

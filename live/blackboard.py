"""Blackboard entries as JSON values, per Groot2 blackboard name (BT.CPP's ``ExportBlackboardToJSON``).

BT.CPP answers Groot2's blackboard request with one JSON object per
subtree blackboard asked for, ``{entry: value}``, values a JSON exporter
knows (strings, numbers, registered types) and null otherwise. homing keeps
one py_trees blackboard with absolute keys (ARCHITECTURE.md, blackboard
keys): a subtree instance's own entries live under ``/<instance>/``, the
rest are the mission's. So the main tree's blackboard is every entry not
under an instance's namespace, named without its leading ``/``
(``robot/time``, ``map/pose``), and an instance's is its namespace's
entries, named as the subtree names them (``goal``).

Values become JSON: numbers, strings, booleans and None as they are;
numpy scalars and small arrays as numbers and lists; dataclasses and named
tuples (``Pose2``, ``Twist2``…) as objects of their fields; lists, tuples
and mappings item by item; anything larger or opaque (an occupancy grid, a
navigator) as a short ``"<TypeName …>"`` string, so a dump stays small.
The entries are read from the server's thread while the tree ticks: each
value is what it was when read, the dump is not one instant's.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Mapping
from typing import Any

import py_trees

MAX_ITEMS = 32  # longest list or mapping written item by item
MAX_DEPTH = 3  # nesting written out before values become "<TypeName>"


def json_value(value: Any, depth: int = 0) -> Any:
    """``value`` as JSON-able data (msgpack packs it), small and never raising."""
    if value is None or isinstance(value, (bool, int, str)):
        return value
    if isinstance(value, float):
        return value if math.isfinite(value) else str(value)
    item = getattr(value, "item", None)
    shape = getattr(value, "shape", None)
    if shape == () and callable(item):  # a numpy scalar
        return json_value(item(), depth)
    if depth >= MAX_DEPTH:
        return f"<{type(value).__name__}>"
    if shape is not None and callable(getattr(value, "tolist", None)):
        size = getattr(value, "size", MAX_ITEMS + 1)
        if size <= MAX_ITEMS:
            return json_value(value.tolist(), depth + 1)
        return f"<{type(value).__name__} {'x'.join(map(str, shape))} {getattr(value, 'dtype', '')}>"
    if dataclasses.is_dataclass(value) and not isinstance(value, type):
        fields = dataclasses.fields(value)
        if len(fields) <= MAX_ITEMS:
            return {f.name: json_value(getattr(value, f.name, None), depth + 1) for f in fields}
    elif isinstance(value, tuple) and hasattr(value, "_fields"):
        return {name: json_value(v, depth + 1) for name, v in zip(value._fields, value, strict=True)}
    elif isinstance(value, Mapping) and len(value) <= MAX_ITEMS:
        items = list(dict(value).items())  # one copy (atomic for a dict): the tick thread may be changing it
        return {str(k): json_value(v, depth + 1) for k, v in items}
    elif isinstance(value, (list, tuple, set, frozenset)) and len(value) <= MAX_ITEMS:
        return [json_value(v, depth + 1) for v in list(value)]
    elif isinstance(value, (list, tuple, set, frozenset, Mapping)):
        return f"<{type(value).__name__} of {len(value)}>"
    return f"<{type(value).__name__}>"


def blackboard_dump(names: list[str], namespaces: Mapping[str, str]) -> dict[str, dict[str, Any]]:
    """``{name: {entry: value}}`` for each known ``name`` (unknown names are left out, as BT.CPP does)."""
    entries = list(py_trees.blackboard.Blackboard.storage.items())  # one copy: the tick thread goes on writing
    instances = sorted((ns for ns in namespaces.values() if ns != "/"), key=len, reverse=True)
    out: dict[str, dict[str, Any]] = {}
    for name in names:
        namespace = namespaces.get(name)
        if namespace is None:
            continue
        board: dict[str, Any] = {}
        for key, value in entries:
            owner = next((ns for ns in instances if key.startswith(ns)), "/")
            if owner == namespace:
                board[key[len(namespace):]] = json_value(value)
        out[name] = board
    return out

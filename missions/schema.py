"""The mission language's vocabulary: top-level keys, parameter types and units, and its JSON Schema.

A parameter value is checked against its :class:`~homing.behaviours.registry.Param`
declaration here: a number where a number is wanted (an ``int`` is a fine
``float``, a ``bool`` is neither), one of the declared ``choices`` for a
string, and for a parameter with a unit either a bare number in that unit or
a string with a compatible unit (``"500 ms"`` for seconds, ``"90 deg"`` for
radians). A string with the wrong dimension (``"5 m"`` for seconds) is an
error, so units cannot be confused the way BT.CPP's milliseconds and
py_trees' seconds are.

:func:`json_schema` turns the registry into a JSON Schema (draft 2020-12) that
an editor's YAML language server uses to complete and check missions.
"""

from __future__ import annotations

import difflib
import math
import re
from collections.abc import Iterable, Mapping
from typing import Any

from homing.behaviours.registry import NODES, REQUIRED, SERVICES, NodeSpec, Param

# Top-level keys of a mission file and what each holds.
TOP_KEYS: dict[str, str] = {
    "mission": "the mission's name (default: the file's stem)",
    "doc": "free text describing the mission",
    "rate": "tick rate [Hz] on the adapter's clock (default 10)",
    "services": "world-model services updated before every tick (default [grid_slam, navigation])",
    "params": "mission parameters with defaults, used in the tree as $name",
    "include": "other mission files whose subtrees this one uses (paths relative to this file)",
    "subtrees": "named trees with parameters, used like nodes",
    "blackboard": "initial blackboard entries the runner writes before the first tick: {key: value}",
    "tree": "the root node",
    "view": "live-view options: {blackboard: [keys to show]}",
}
SUBTREE_KEYS: dict[str, str] = {
    "doc": "what the subtree does",
    "params": "its parameters: name: default (null = required)",
    "tree": "the subtree's root node",
}
DEFAULT_RATE = 10.0  # [Hz]
MIN_RATE = 1.0  # [Hz] slower, and the robot drives blind on one command for over a second
MAX_RATE = 1000.0  # [Hz] faster than any sensor or the base's 50 Hz control loop can use
DEFAULT_SERVICES = ("grid_slam", "navigation")

# Units a parameter may declare, and the spellings accepted for each, as factors to it.
UNITS: dict[str, dict[str, float]] = {
    "s": {"ms": 1e-3, "s": 1.0, "sec": 1.0, "min": 60.0, "h": 3600.0},
    "m": {"mm": 1e-3, "cm": 1e-2, "m": 1.0},
    "rad": {"rad": 1.0, "deg": math.pi / 180.0},
    "m/s": {"m/s": 1.0, "cm/s": 1e-2},
    "rad/s": {"rad/s": 1.0, "deg/s": math.pi / 180.0},
    "Hz": {"Hz": 1.0, "hz": 1.0, "kHz": 1e3},
    "%": {"%": 1.0},
    "V": {"V": 1.0, "mV": 1e-3},
}
DIMENSION = {"s": "a time", "m": "a length", "rad": "an angle", "m/s": "a speed", "rad/s": "a turn rate",
             "Hz": "a rate", "%": "a percentage", "V": "a voltage"}  # fmt: skip
_QUANTITY = re.compile(r"^\s*([-+]?(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?)\s*([A-Za-z%/]+)\s*$")
_TYPE_NAMES = {float: "a number", int: "an integer", bool: "true or false", str: "a string", list: "a list"}


def suggest(word: str, options: Iterable[str]) -> str:
    """`` (did you mean 'x'?)`` for the closest option, or an empty string."""
    close = difflib.get_close_matches(str(word), list(options), n=1, cutoff=0.6)
    if not close:
        lowered = {o.lower(): o for o in options}
        if str(word).lower() in lowered:
            close = [lowered[str(word).lower()]]
    return f" (did you mean '{close[0]}'?)" if close else ""


def parse_quantity(text: str, unit: str) -> float:
    """``"500 ms"`` → 0.5 for unit ``"s"``; a bare number is taken in ``unit``. Raises ValueError."""
    text = str(text).strip()
    try:
        return float(text)
    except ValueError:
        pass
    m = _QUANTITY.match(text)
    spellings = UNITS.get(unit, {unit: 1.0} if unit else {})
    if not m:
        accepted = ", ".join(spellings) if spellings else "no unit"
        raise ValueError(f"'{text}' is not a number with a unit (accepted units: {accepted})")
    number, given = float(m.group(1)), m.group(2)
    if given in spellings:
        return number * spellings[given]
    for dim, table in UNITS.items():
        if given in table:
            want = DIMENSION.get(unit, f"'{unit}'") if unit else "a plain number"
            raise ValueError(
                f"wrong unit '{given}' ({DIMENSION[dim]}) where {want} is expected"
                + (f" (use {', '.join(spellings)})" if spellings else "")
            )
    raise ValueError(f"unknown unit '{given}'{suggest(given, spellings)} (use {', '.join(spellings) or 'no unit'})")


def _types(param: Param) -> tuple[type, ...]:
    return param.type if isinstance(param.type, tuple) else (param.type,)


def check_value(param: Param, value: Any) -> Any:
    """The value converted to the parameter's type and unit, within its bounds; raises ValueError with a one-line reason."""
    out = _convert(param, value)
    if isinstance(out, (int, float)) and not isinstance(out, bool):
        _check_number(param, out, value)
    return out


def _check_number(param: Param, number: float, given: Any) -> None:
    """Finite (NaN only where the default is NaN) and within the declared bounds, or ValueError."""
    unit = f" {param.unit}" if param.unit and param.unit != "%" else param.unit
    shown = given if isinstance(given, str) else f"{number:g}{unit}"
    if math.isnan(number):
        if isinstance(param.default, float) and math.isnan(param.default):
            return
        raise ValueError(f"'{param.name}' needs a number, not NaN")
    if math.isinf(number):
        raise ValueError(f"'{param.name}' needs a finite number, not {shown}")
    if param.above is not None and not number > param.above:
        raise ValueError(f"'{param.name}' must be above {param.above:g}{unit}, not {shown}")
    if param.minimum is not None and number < param.minimum:
        raise ValueError(f"'{param.name}' must be at least {param.minimum:g}{unit}, not {shown}")
    if param.maximum is not None and number > param.maximum:
        raise ValueError(f"'{param.name}' must be at most {param.maximum:g}{unit}, not {shown}")


def _convert(param: Param, value: Any) -> Any:
    types = _types(param)
    if value is None:
        if param.default is None:
            return None
        raise ValueError(f"'{param.name}' needs {_expected(types, param)}, not null")
    if isinstance(value, bool):
        if bool in types:
            return value
        raise ValueError(f"'{param.name}' needs {_expected(types, param)}, not {str(value).lower()}")
    if isinstance(value, (int, float)):
        if float in types:
            return float(value)
        if int in types and isinstance(value, int):
            return value
        if int in types and float(value).is_integer():
            return int(value)
        raise ValueError(f"'{param.name}' needs {_expected(types, param)}, not {value!r}")
    if isinstance(value, str):
        if float in types and param.unit:
            return parse_quantity(value, param.unit)
        if str in types:
            if param.choices and value not in param.choices:
                raise ValueError(
                    f"'{param.name}' must be one of {', '.join(param.choices)}, not '{value}'"
                    + suggest(value, param.choices)
                )
            return value
        if (float in types or int in types) and not param.unit and not _QUANTITY.match(value):
            raise ValueError(f"'{param.name}' needs {_expected(types, param)}, not the string '{value}'")
        if float in types or int in types:
            try:
                number = parse_quantity(value, param.unit)
            except ValueError as err:
                raise ValueError(f"'{param.name}': {err}") from None
            return number if float in types or not number.is_integer() else int(number)
        raise ValueError(f"'{param.name}' needs {_expected(types, param)}, not the string '{value}'")
    if isinstance(value, list) and list in types:
        return list(value)
    kind = "a list" if isinstance(value, list) else "a mapping" if isinstance(value, dict) else type(value).__name__
    raise ValueError(f"'{param.name}' needs {_expected(types, param)}, not {kind}")


def _expected(types: tuple[type, ...], param: Param) -> str:
    names = " or ".join(_TYPE_NAMES.get(t, t.__name__) for t in types)
    return f"{names} [{param.unit}]" if param.unit else names


def describe_param(param: Param) -> str:
    """One line for ``homing nodes``: ``seconds: float [s] = 5 — doc``."""
    types = "|".join(t.__name__ for t in _types(param))
    unit = f" [{param.unit}]" if param.unit else ""
    default = "required" if param.default is REQUIRED else f"= {param.default!r}"
    choices = f" one of {', '.join(param.choices)}" if param.choices else ""
    limits = [f"> {param.above:g}" if param.above is not None else "",
              f"≥ {param.minimum:g}" if param.minimum is not None else "",
              f"≤ {param.maximum:g}" if param.maximum is not None else ""]
    bounds = f" ({', '.join(x for x in limits if x)})" if any(limits) else ""
    return f"{param.name}: {types}{unit} {default}{bounds}{choices}" + (f" — {param.doc}" if param.doc else "")


# --------------------------------------------------------------------------- JSON Schema


def _bounds(param: Param) -> dict[str, Any]:
    out: dict[str, Any] = {}
    if param.minimum is not None:
        out["minimum"] = param.minimum
    if param.maximum is not None:
        out["maximum"] = param.maximum
    if param.above is not None:
        out["exclusiveMinimum"] = param.above
    return out


def _param_schema(param: Param) -> dict[str, Any]:
    alts: list[dict[str, Any]] = []
    non_negative = (param.minimum is not None and param.minimum >= 0) or (param.above is not None and param.above >= 0)
    for t in _types(param):
        if t is float:
            alts.append({"type": "number", **_bounds(param)})
            if param.unit:
                units = "|".join(re.escape(u) for u in UNITS.get(param.unit, {param.unit: 1}))
                sign = "[+]?" if non_negative else "[-+]?"
                number = r"([0-9]+\.?[0-9]*|\.[0-9]+)([eE][-+]?[0-9]+)?"
                alts.append({"type": "string", "pattern": rf"^\s*{sign}{number}\s*({units})\s*$"})
        elif t is int:
            alts.append({"type": "integer", **_bounds(param)})
        elif t is bool:
            alts.append({"type": "boolean"})
        elif t is str:
            alts.append({"type": "string", "enum": list(param.choices)} if param.choices else {"type": "string"})
        elif t is list:
            alts.append({"type": "array"})
    alts.append({"type": "string", "pattern": r"^\$[A-Za-z_][A-Za-z0-9_]*$"})  # $name substitution
    alts.append({"type": "string", "pattern": r"^\{\s*[@/A-Za-z_=][A-Za-z0-9_./@-]*\s*\}$"})  # "{key}": a port
    alts.append({"type": "object", "minProperties": 1, "maxProperties": 1,
                 "additionalProperties": {"type": "null"}})  # {key} unquoted: YAML's one-entry mapping
    out: dict[str, Any] = {"anyOf": alts}
    doc = param.doc + (f" [{param.unit}]" if param.unit else "")
    if doc:
        out["description"] = doc
    if param.default is not REQUIRED and isinstance(param.default, (int, float, str, bool, list)):
        out["default"] = param.default
    return out


def _node_schema(spec: NodeSpec, ref: str) -> dict[str, Any]:
    """``{Kind: body}`` for one registered node; its children are ``$ref: ref``."""
    props: dict[str, Any] = {"name": {"type": "string", "description": "the node's name in the view and logs"}}
    for p in spec.params:
        props[p.name] = _param_schema(p)
    required = [p.name for p in spec.params if p.required]
    for slot in spec.child_slots:
        if slot == "children":
            props[slot] = {"type": "array", "minItems": 1, "items": {"$ref": ref}}
        else:
            props[slot] = {"$ref": ref}
        if slot not in spec.optional:
            required.append(slot)
    body: dict[str, Any] = {"type": "object", "properties": props, "additionalProperties": False}
    if required:
        body["required"] = required
    forms: list[dict[str, Any]] = [body]
    if spec.child_slots == ("children",):
        forms.append({"type": "array", "minItems": 1, "items": {"$ref": ref}})
    if not required:
        forms.append({"type": "null"})
    needed = [p for p in spec.params if p.required]
    if not spec.child_slots and len(needed) == 1:
        forms.append(_param_schema(needed[0]))  # a leaf's only required parameter given alone: Wait: 5 s
    return {
        "type": "object",
        "properties": {spec.name: {"anyOf": forms, "description": spec.doc}},
        "required": [spec.name],
        "additionalProperties": False,
    }


def _subtree_use(name: str, params: Iterable[str]) -> dict[str, Any]:
    """``{Name: {its parameters}}``: a subtree used like a node."""
    props: dict[str, Any] = {"name": {"type": "string"}, **{p: {} for p in params}}
    body = {"anyOf": [{"type": "object", "properties": props, "additionalProperties": False}, {"type": "null"}],
            "description": f"subtree '{name}'"}
    return {"type": "object", "properties": {name: body}, "required": [name], "additionalProperties": False}


def _node_forms(ref: str) -> list[dict[str, Any]]:
    """Every registered node's form, children referring to ``ref``, and a bare name for those that need nothing."""
    forms = [_node_schema(NODES[n], ref) for n in sorted(NODES)]
    bare = sorted(n for n, s in NODES.items() if not any(p.required for p in s.params) and not s.child_slots)
    forms.append({"type": "string", "enum": bare, "description": "a node without parameters"})
    return forms


def _service_forms() -> list[dict[str, Any]]:
    forms: list[dict[str, Any]] = [{"type": "string", "enum": sorted(SERVICES)}]
    for name in sorted(SERVICES):
        props = {p.name: _param_schema(p) for p in SERVICES[name].params}
        body = {"anyOf": [{"type": "object", "properties": props, "additionalProperties": False}, {"type": "null"}],
                "description": SERVICES[name].doc}
        forms.append({"type": "object", "properties": {name: body}, "required": [name], "additionalProperties": False})
    return forms


def json_schema(subtrees: Mapping[str, Iterable[str]] | None = None) -> dict[str, Any]:
    """A JSON Schema of mission files for the nodes registered now (call ``load_nodes()`` first).

    With ``subtrees`` (name → parameter names, e.g. one mission's and its
    includes'), a node is a registered node or one of those subtrees, and
    anything else is an unknown node — exactly as ``homing check`` decides.
    Without, the schema serves any mission: a file with no ``subtrees:``
    and no ``include:`` gets the same exact check; in one that has them, a
    single-key mapping that names no registered node passes as a subtree
    (the schema cannot see another file's subtrees).
    """
    subtree = {"type": "object", "minProperties": 1, "maxProperties": 1,
               "not": {"anyOf": [{"required": [n]} for n in sorted(NODES)]},
               "description": "a subtree, by name, with its parameters"}  # fmt: skip
    defs: dict[str, Any] = {"node": {"anyOf": _node_forms("#/$defs/node")}}
    if subtrees is not None:
        defs["node"]["anyOf"] += [_subtree_use(name, params) for name, params in sorted(subtrees.items())]
        loose = "#/$defs/node"
    else:
        defs["node_or_subtree"] = {"anyOf": [*_node_forms("#/$defs/node_or_subtree"), subtree]}
        loose = "#/$defs/node_or_subtree"

    def trees(ref: str) -> dict[str, Any]:
        return {
            "tree": {"$ref": ref},
            "subtrees": {
                "type": "object",
                "additionalProperties": {
                    "type": "object",
                    "properties": {"doc": {"type": "string"}, "params": {"type": "object"}, "tree": {"$ref": ref}},
                    "required": ["tree"],
                    "additionalProperties": False,
                },
            },
        }

    schema: dict[str, Any] = {
        "$schema": "https://json-schema.org/draft/2020-12/schema",
        "$id": "https://homing.invalid/mission.schema.json",
        "title": "homing mission",
        "type": "object",
        "properties": {
            "mission": {"type": "string", "description": TOP_KEYS["mission"]},
            "doc": {"type": "string"},
            "rate": {"type": "number", "minimum": MIN_RATE, "maximum": MAX_RATE, "description": TOP_KEYS["rate"]},
            "services": {"anyOf": [{"type": "array", "items": {"anyOf": _service_forms()}}, {"type": "null"}],
                         "description": TOP_KEYS["services"]},
            "params": {"anyOf": [{"type": "object", "propertyNames": {"pattern": r"^[A-Za-z_][A-Za-z0-9_]*$"}},
                                 {"type": "null"}], "description": TOP_KEYS["params"]},
            "include": {"anyOf": [{"type": "string"}, {"type": "array", "items": {"type": "string"}}]},
            "tree": {"description": TOP_KEYS["tree"]},
            "subtrees": {"description": "named trees with parameters, used like nodes"},
            "blackboard": {"type": "object", "description": TOP_KEYS["blackboard"]},
            "view": {"type": "object", "properties": {"blackboard": {"type": "array", "items": {"type": "string"}}},
                     "additionalProperties": False},
        },
        "required": ["tree"],
        "additionalProperties": False,
        "$defs": defs,
    }
    if subtrees is not None:
        schema["allOf"] = [{"properties": trees(loose)}]
    else:
        has_subtrees = {"anyOf": [{"required": ["subtrees"]}, {"required": ["include"]}]}
        schema["allOf"] = [{"if": has_subtrees, "then": {"properties": trees(loose)},
                            "else": {"properties": trees("#/$defs/node")}}]
    return schema

"""Compile a mission's YAML into a py_trees tree, checking everything before the first tick.

A node in YAML is a one-key mapping ``{Kind: body}`` (or a bare ``Kind`` for
a node without required parameters). ``Kind`` is a registered node
(:data:`homing.behaviours.registry.NODES`) or a subtree; ``body`` holds its
parameters, its optional ``name:``, and its children (``children: [...]``
for a composite, which may also be given as the body itself; ``child:`` for
a decorator; named branches such as ``recovery:`` or ``condition:`` for
nodes that declare them). A scalar body sets a leaf's only required
parameter (``Wait: 5``). A string value ``$name`` is replaced by the
parameter ``name`` of the enclosing subtree or of the mission (``$$`` for a
literal dollar).

Blackboard ports (:mod:`homing.behaviours.ports`): a parameter written
``"{key}"`` is read from the blackboard each time the node starts. The
compiler resolves the key: ``{/a/b}`` absolute, ``{@k}`` the root's ``/k``,
``{=}`` the parameter's own name, and a bare ``{k}`` is ``/k`` at the top of
the mission; inside a subtree it is what the caller gave the subtree's
parameter ``k`` (``Sub: {k: "{target}"}`` remaps it to the caller's
``target``, a plain value fixes it), else the subtree instance's own entry
``/<instance>/k`` (BT.CPP's isolated subtree blackboards). A parameter that
names a key (``goal_key``, ``key``) takes the key itself, with or without
braces, and resolves it the same way. ``blackboard:`` entries are written
by the runner before the first tick, as an application sets BT.CPP's
blackboard (Nav2's navigator writes ``goal``).

Errors are collected, never raised one by one (:class:`~homing.missions.loader.Problems`):
unknown node or parameter (with "did you mean"), wrong type or unit,
missing required parameter or child, unknown subtree, service or include,
include cycle, subtree recursion, duplicate names, and a blackboard key that
a node reads but no node, service or the runner writes. The tree is only
returned when there are none.
"""

from __future__ import annotations

import uuid
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, cast

from homing.behaviours import load_nodes
from homing.behaviours.expression import Const, ScriptSyntaxError
from homing.behaviours.ports import Port, PortRef, accepts_port, parse_port, placeholder, ported
from homing.behaviours.registry import NODES, SERVICES, NodeSpec, ServiceSpec
from homing.missions.loader import Loc, MissionSource, Problems, Subtree, _where, load_source
from homing.missions.schema import check_value, suggest
from py_trees.behaviour import Behaviour

from homing.errors import UserError
from homing.yamlfile import LocatedDict, LocatedList

RUNNER_WRITES = ("/robot/observation", "/robot/time")
ALWAYS_WRITTEN = (*RUNNER_WRITES, "/cmd_vel")


class _Unbound:
    """A required subtree parameter while the subtree is checked on its own."""

    def __repr__(self) -> str:
        return "<unbound>"


UNBOUND: Any = _Unbound()


@dataclass
class NodeInfo:
    """What the compiler knows of one built node: its kind, parameters and source location."""

    kind: str  # registry kind: action, condition, decorator, composite
    spec: str  # the registry name, e.g. "Wait" or "sequence"
    params: dict[str, Any]
    file: Path
    loc: Loc
    subtree: str | None = None  # set on the root of a subtree instance
    reads: tuple[str, ...] = ()
    writes: tuple[str, ...] = ()
    ports: dict[str, str] = field(default_factory=dict)  # parameter → the key it is read from
    # On the root of subtree instances: (subtree name, the instance's blackboard namespace "/<instance>/"), outermost
    # first (a subtree whose tree is another subtree's call roots both instances at one node).
    instances: list[tuple[str, str]] = field(default_factory=list)


@dataclass
class CompiledMission:
    """A checked mission: the root behaviour, its services, and per-node information for view and logs."""

    source: MissionSource
    root: Behaviour
    info: dict[uuid.UUID, NodeInfo]
    services: list[tuple[ServiceSpec, dict[str, Any]]] = field(default_factory=list)
    warnings: list[str] = field(default_factory=list)
    blackboard: dict[str, Any] = field(default_factory=dict)  # initial entries the runner writes, by absolute key

    @property
    def name(self) -> str:
        return self.source.name

    @property
    def rate(self) -> float:
        return self.source.rate

    def summary(self) -> str:
        kinds: dict[str, int] = {}
        for i in self.info.values():
            kinds[i.kind] = kinds.get(i.kind, 0) + 1
        parts = ", ".join(f"{n} {k}{'s' if n != 1 else ''}" for k, n in sorted(kinds.items()))
        services = ", ".join(s.name for s, _ in self.services) or "none"
        return (
            f"{self.source.path}: ok: mission '{self.name}', {len(self.info)} nodes ({parts}), "
            f"{len(self.source.subtrees)} subtrees, services: {services}, {self.rate:g} Hz"
        )


@dataclass
class _Scope:
    """Where a node is being expanded: its file, parameter values, subtree chain and used names."""

    file: Path
    values: dict[str, Any]
    chain: tuple[str, ...] = ()
    names: dict[str, Loc] = field(default_factory=dict)
    build: bool = True
    context: str = ""
    namespace: str = "/"  # where a bare {key} lives: "/" at the top, "/<instance>/" in a subtree instance


class Compiler:
    """Expands a :class:`MissionSource` against the registry, collecting every problem."""

    def __init__(self, source: MissionSource, problems: Problems):
        self.source = source
        self.problems = problems
        self.info: dict[uuid.UUID, NodeInfo] = {}
        self.reads: list[tuple[str, Path, Loc, str, str]] = []  # key, file, place, node, subtree context
        self.writes: set[str] = set(ALWAYS_WRITTEN)
        self.used_subtrees: set[str] = set()
        self.display_names: dict[str, int] = {}
        self.namespaces: dict[str, int] = {}
        self.blackboard: dict[str, Any] = {}
        self.unknown_service = False

    def error(self, scope: _Scope, loc: Loc, message: str) -> None:
        self.problems.add(scope.file, loc, message + scope.context)

    # -- the whole mission ---------------------------------------------------------
    def compile(self) -> tuple[Behaviour | None, list[tuple[ServiceSpec, dict[str, Any]]]]:
        src = self.source
        for name, sub in src.subtrees.items():
            if name in NODES:
                self.problems.add(sub.file, sub.loc, f"subtree '{name}' has the name of a registered node ({NODES[name].kind})")
        services = self.services()
        self.initial_entries()
        root = None
        if src.tree is not None:
            scope = _Scope(src.path, dict(src.params))
            root = self.node(src.tree, src.tree_container, "tree", scope)
        for name, sub in src.subtrees.items():
            if name not in self.used_subtrees:  # still check what nobody uses yet
                values = {k: (UNBOUND if v is None else v) for k, v in sub.params.items()}
                self.node(sub.tree, sub.tree_container, "tree", _Scope(sub.file, values, (name,), build=False))
        self.check_keys(services)
        return root, services

    def services(self) -> list[tuple[ServiceSpec, dict[str, Any]]]:
        out: list[tuple[ServiceSpec, dict[str, Any]]] = []
        path = self.source.path
        seen: list[str] = []
        for use in self.source.services:
            spec = SERVICES.get(use.name)
            if spec is None:
                known = ", ".join(sorted(SERVICES)) or "none is registered yet"
                hint = " — declare 'services: [...]' in the mission (the default is [grid_slam, navigation])" if use.name in ("grid_slam", "navigation") else ""
                self.problems.add(path, use.loc, f"unknown service '{use.name}'{suggest(use.name, SERVICES)} (registered: {known}){hint}")
                self.unknown_service = True
                continue
            if use.name in seen:
                self.problems.add(path, use.loc, f"duplicate service '{use.name}'")
                continue
            for req in spec.requires:
                if req not in seen:
                    self.problems.add(path, use.loc, f"service '{use.name}' needs '{req}' listed before it")
            params = self.params_for(spec.name, spec.params, dict(use.params), use.container, use.loc, _Scope(path, dict(self.source.params)), "service")
            seen.append(use.name)
            self.writes.update(spec.writes)
            if params is not None:
                out.append((spec, params))
        return out

    def initial_entries(self) -> None:
        """The mission's ``blackboard:`` entries: keys resolved, ``$params`` substituted, counted as written."""
        src = self.source
        scope = _Scope(src.path, dict(src.params))
        for key, value in src.blackboard.items():
            loc = src.blackboard_locs.get(key, (1, 1))
            ref = parse_port(key) or (PortRef(key) if isinstance(key, str) and key.strip() else None)
            resolved = self.resolve_port(ref, scope, "") if ref is not None else None
            if not isinstance(resolved, Port):
                self.error(scope, loc, f"blackboard: '{key}' is not a blackboard key")
                continue
            value = self.substitute(value, scope, loc)
            if value is UNBOUND:
                continue
            self.blackboard[resolved.key] = value
            self.writes.add(resolved.key)

    def resolve_port(self, ref: PortRef, scope: _Scope, param: str) -> Any:
        """What ``{ref}`` stands for in ``scope``: a :class:`Port`, a subtree parameter's fixed value, or UNBOUND."""
        text = param if ref.text == "=" else ref.text
        if text.startswith("@"):
            return Port("/" + text[1:].lstrip("/"))
        if text.startswith("/"):
            return Port(text)
        if scope.chain and text in scope.values:
            return scope.values[text]
        return Port(scope.namespace + text)

    def check_keys(self, services: list[tuple[ServiceSpec, dict[str, Any]]]) -> None:
        if self.unknown_service:
            return  # the unknown service may well write what is missing: fix that first
        for key, file, loc, node, context in self.reads:
            if key in self.writes:
                continue
            writers = sorted(s for s, spec in SERVICES.items() if key in spec.writes)
            hint = f"; the service '{writers[0]}' writes it" if writers else ""
            self.problems.add(file, loc, f"{node} reads '{key}' but nothing writes it (no node, service or the runner){hint}{context}")

    # -- one node -------------------------------------------------------------------
    def node(self, raw: Any, container: Any, key: Any, scope: _Scope) -> Behaviour | None:
        loc = _where(container, key)
        if isinstance(raw, str):
            kind, body, body_container = raw, None, None
        elif isinstance(raw, LocatedDict) and len(raw) == 1:
            kind, body = next(iter(raw.items()))
            body_container = raw
        elif isinstance(raw, LocatedDict) and raw:
            keys = list(raw)
            self.error(scope, loc, f"a node is one mapping key, its kind; found {len(keys)} keys ({', '.join(map(str, keys))}): indent the parameters under the kind")
            return None
        else:
            self.error(scope, loc, f"expected a node ({{Kind: parameters}} or a bare Kind), found {_what(raw)}")
            return None
        kind_loc = _where(raw, kind, value=False) if isinstance(raw, LocatedDict) else loc
        if not isinstance(kind, str):
            self.error(scope, kind_loc, f"a node's kind is a name, not {_what(kind)}")
            return None
        if kind in self.source.subtrees:
            return self.subtree(kind, body, body_container, kind_loc, scope)
        spec = NODES.get(kind)
        if spec is None:
            options = [*NODES, *self.source.subtrees]
            self.error(scope, kind_loc, f"unknown node '{kind}'{suggest(kind, options)}")
            return None
        return self.registered(spec, body, raw if isinstance(raw, LocatedDict) else container, kind if isinstance(raw, LocatedDict) else key, kind_loc, scope)

    def registered(self, spec: NodeSpec, body: Any, container: Any, key: Any, loc: Loc, scope: _Scope) -> Behaviour | None:
        slots = spec.child_slots
        body_loc = _where(container, key)
        # Normalise the body into a mapping of parameters and children.
        if body is None:
            body = LocatedDict()
            body.loc = body_loc
        elif isinstance(body, LocatedList) and slots == ("children",):
            items = body
            body = LocatedDict(children=items)
            body.loc, body.value_loc["children"] = body_loc, body_loc
        elif not isinstance(body, LocatedDict):
            required = [p for p in spec.params if p.required]
            if not slots and len(required) == 1:
                scalar = body
                body = LocatedDict({required[0].name: scalar})
                body.loc = body.value_loc[required[0].name] = body_loc
            else:
                self.error(scope, body_loc, f"{spec.name}: give its parameters as a mapping, not {_what(body)}")
                return None
        name = body.get("name", spec.name)
        if "name" in body and not isinstance(name, str):
            self.error(scope, _where(body, "name"), f"name: needs a string, not {_what(name)}")
            name = spec.name
        elif "name" in body:
            first = scope.names.get(name)
            if first is not None:
                self.error(scope, _where(body, "name"), f"duplicate name '{name}' (first used at line {first[0]})")
            else:
                scope.names[name] = _where(body, "name")
        raw_params = {k: v for k, v in body.items() if k != "name" and k not in slots}
        params = self.params_for(spec.name, spec.params, raw_params, body, loc, scope, spec.kind, slots)
        children: dict[str, Any] = {}
        ok = params is not None
        for slot in slots:
            if slot not in body and slot in spec.optional:
                children[slot] = None
                continue
            if slot not in body:
                self.error(scope, loc, f"{spec.name} needs '{slot}:'" + (" (a list of nodes)" if slot == "children" else " (a node)"))
                ok = False
                continue
            if slot == "children":
                items = body[slot]
                if not isinstance(items, LocatedList) or not items:
                    self.error(scope, _where(body, slot), f"{spec.name}: children: needs a non-empty list of nodes")
                    ok = False
                    continue
                built = [self.node(item, items, i, scope) for i, item in enumerate(items)]
                ok = ok and all(b is not None for b in built)
                children[slot] = built
            else:
                child = self.node(body[slot], body, slot, scope)
                ok = ok and child is not None
                children[slot] = child
        extra: dict[str, Any] = {}
        ports: dict[str, Port] = {}
        reads: tuple[str, ...] = ()
        writes: tuple[str, ...] = ()
        if params is not None:
            ports = {k: v for k, v in params.items() if isinstance(v, Port)}
            plain = {k: v for k, v in params.items() if not isinstance(v, Port)}
            reads, writes = spec.keys(plain)
            reads = (*reads, *(p.key for p in ports.values()))
            hook = getattr(spec.factory, "compile_keys", None)
            if hook is not None and not any(v is UNBOUND for v in plain.values()) and not ports:
                try:
                    extra, more_reads, more_writes = hook(plain, lambda text: self._script_key(text, scope))
                except ScriptSyntaxError as err:
                    self.error(scope, loc, f"{spec.name}: {err}")
                    return None
                reads, writes = (*reads, *more_reads), (*writes, *more_writes)
            self.writes.update(writes)
            self.reads.extend((k, scope.file, loc, f"{name} ({spec.name})", scope.context) for k in reads)
        if not ok or not scope.build or params is None:
            return None
        if any(v is UNBOUND for v in params.values()):
            return None
        declared = {p.name: p for p in spec.params}
        values = {k: (placeholder(declared[k]) if isinstance(v, Port) else v) for k, v in params.items()}
        factory = ported(cast(type, spec.factory)) if ports else spec.factory
        try:
            behaviour = factory(name=self.display(name), **values, **extra, **children)
        except Exception as err:  # a constructor's complaint about a value is the user's mistake
            self.error(scope, loc, f"{spec.name}: {err}")
            return None
        for key in ports:
            if not accepts_port(behaviour, key):
                self.error(scope, _where(body, key), f"{spec.name}: '{key}' is fixed when the tree is built and cannot be read from the blackboard")
                return None
        if ports:
            cast(Any, behaviour).attach_ports({k: (p, declared[k]) for k, p in ports.items()}, check_value)
        self.info[behaviour.id] = NodeInfo(spec.kind, spec.name, params, scope.file, loc, None, tuple(reads), tuple(writes),
                                           {k: p.key for k, p in ports.items()})  # fmt: skip
        return behaviour

    def _script_key(self, text: str, scope: _Scope) -> Any:
        """A script's name → its absolute key, or a Const for a subtree parameter fixed to a value."""
        inner = text[1:-1].strip() if text.startswith("{") else text
        resolved = self.resolve_port(PortRef(inner), scope, "")
        if isinstance(resolved, Port):
            return resolved.key
        return Const(resolved)

    def params_for(
        self, owner: str, declared: tuple[Any, ...], raw: dict[str, Any], container: Any, loc: Loc,
        scope: _Scope, kind: str, slots: tuple[str, ...] = (),
    ) -> dict[str, Any] | None:  # fmt: skip
        """Check parameters against their declarations; None if any is wrong."""
        table = {p.name: p for p in declared}
        key_params = _key_params(owner)
        out: dict[str, Any] = {}
        ok = True
        for key, value in raw.items():
            where = _where(container, key, value=False) if isinstance(container, LocatedDict) else loc
            param = table.get(key)
            if param is None:
                known = [*table, *slots, *(("name",) if kind != "service" else ())]
                listing = ", ".join(known) if known else "none"
                self.error(scope, where, f"unknown parameter '{key}' of {owner}{suggest(str(key), known)} (parameters: {listing})")
                ok = False
                continue
            vloc = _where(container, key) if isinstance(container, LocatedDict) else loc
            value = self.substitute(value, scope, vloc)
            ref = parse_port(value)
            if ref is None and key in key_params and isinstance(value, str) and value.strip():
                ref = PortRef(value.strip())  # a key parameter names its key with or without braces
            if ref is not None:
                value = self.resolve_port(ref, scope, str(key))
            if value is UNBOUND:
                out[key] = UNBOUND
                continue
            if isinstance(value, Port):
                if key in key_params:
                    out[key] = value.key
                elif kind == "service":
                    self.error(scope, vloc, f"{owner}: a service's '{key}' is fixed at start and cannot be read from the blackboard")
                    ok = False
                else:
                    out[key] = value
                continue
            try:
                out[key] = check_value(param, value)
            except ValueError as err:
                self.error(scope, _where(container, key) if isinstance(container, LocatedDict) else loc, f"{owner}: {err}")
                ok = False
        for param in declared:
            if param.name not in out and param.name not in raw:
                if param.required:
                    self.error(scope, loc, f"{owner} is missing the required parameter '{param.name}'")
                    ok = False
                else:
                    out[param.name] = param.default
        return out if ok else None

    def substitute(self, value: Any, scope: _Scope, loc: Loc) -> Any:
        if isinstance(value, str) and value.startswith("$"):
            if value.startswith("$$"):
                return value[1:]
            name = value[1:]
            if name in scope.values:
                return scope.values[name]
            where = f"subtree '{scope.chain[-1]}'" if scope.chain else "the mission"
            self.error(scope, loc, f"unknown parameter '${name}'{suggest(name, scope.values)} ({where} has: {', '.join(scope.values) or 'none'})")
            return UNBOUND
        if isinstance(value, list):
            return [self.substitute(v, scope, loc) for v in value]
        return value

    def subtree(self, name: str, body: Any, container: Any, loc: Loc, scope: _Scope) -> Behaviour | None:
        sub: Subtree = self.source.subtrees[name]
        self.used_subtrees.add(name)
        if name in scope.chain:
            self.error(scope, loc, f"subtree '{name}' uses itself ({' → '.join([*scope.chain, name])})")
            return None
        if body is None:
            body = LocatedDict()
            body.loc = loc
        if not isinstance(body, LocatedDict):
            self.error(scope, loc, f"subtree '{name}': give its parameters as a mapping, not {_what(body)}")
            return None
        values: dict[str, Any] = {}
        instance = body.get("name", name)
        ok = True
        for key, value in body.items():
            if key == "name":
                continue
            if key not in sub.params:
                self.error(scope, _where(body, key, value=False), f"unknown parameter '{key}' of subtree '{name}'{suggest(str(key), sub.params)} (parameters: {', '.join(sub.params) or 'none'})")
                ok = False
                continue
            value = self.substitute(value, scope, _where(body, key))
            ref = parse_port(value)
            values[key] = self.resolve_port(ref, scope, str(key)) if ref is not None else value  # in the caller's scope
        namespace = f"{scope.namespace}{self.instance(scope.namespace + str(instance))}/"
        for key, default in sub.params.items():
            if key not in values:
                ref = parse_port(default)
                if default is None:
                    self.error(scope, loc, f"subtree '{name}' is missing the required parameter '{key}'")
                    values[key] = UNBOUND
                    ok = False
                elif ref is not None:  # an entry of the subtree's own unless the caller remaps it
                    values[key] = self.resolve_port(ref, _Scope(sub.file, {}, namespace=namespace), str(key))
                else:
                    values[key] = default
        inner = _Scope(
            sub.file, values, (*scope.chain, name), {}, scope.build and ok,
            scope.context or f" (in subtree '{name}' used at {scope.file.name}:{loc[0]}:{loc[1]})",
            namespace,
        )
        root = self.node(sub.tree, sub.tree_container, "tree", inner)
        if root is not None:
            self.info[root.id].subtree = str(instance)
            self.info[root.id].instances.insert(0, (name, namespace))
            explicit = isinstance(sub.tree, LocatedDict) and any(
                isinstance(b, LocatedDict) and "name" in b for b in sub.tree.values()
            )
            if not explicit:
                root.name = self.display(str(instance))
        return root if ok else None

    def instance(self, path: str) -> str:
        """A unique name for a subtree instance's own blackboard entries: ``Navigate``, then ``Navigate#2``."""
        n = self.namespaces.get(path, 0) + 1
        self.namespaces[path] = n
        base = path.rsplit("/", 1)[-1]
        return base if n == 1 else f"{base}#{n}"

    def display(self, name: str) -> str:
        """A unique name for logs and the view: the second 'Wait' is 'Wait#2'."""
        n = self.display_names.get(name, 0) + 1
        self.display_names[name] = n
        return name if n == 1 else f"{name}#{n}"


def _key_params(owner: str) -> set[str]:
    """The parameters of node ``owner`` whose value is a blackboard key (``$name`` in its reads or writes)."""
    spec = NODES.get(owner)
    if spec is None:
        return set()
    return {k[1:] for k in (*spec.reads, *spec.writes) if k.startswith("$")}


def _what(value: Any) -> str:
    if value is None:
        return "nothing"
    if isinstance(value, bool):
        return str(value).lower()
    if isinstance(value, dict):
        return "a mapping"
    if isinstance(value, list):
        return "a list"
    return f"{type(value).__name__} {value!r}"


def compile_mission(path: str | Path, overrides: dict[str, Any] | None = None) -> CompiledMission:
    """Load, check and build a mission; raises :class:`~homing.errors.UserErrors` listing every problem."""
    warnings = load_nodes()
    problems = Problems()
    try:
        source = load_source(path, overrides, problems)
        compiler = Compiler(source, problems)
        root, services = compiler.compile()
    except UserError as err:  # defensive: loaders report through problems, but never let one escape raw
        problems.extend(err)
        root, services = None, []
    problems.raise_if_any()
    assert root is not None
    return CompiledMission(source, root, compiler.info, services, warnings, compiler.blackboard)

"""Read a mission file and its includes into one source: top level, parameters, subtrees, tree.

Files are read with :mod:`homing.yamlfile`, so everything keeps its
``line:col``. ``include:`` paths are relative to the including file (then
the bundled ``homing/missions/library/``); an include that comes back to a
file on the current include chain is a cycle and is reported where the
chain closes. Subtrees from every file share one namespace. Nothing here
knows the node registry: the compiler (:mod:`homing.missions.compiler`)
checks nodes, parameters and keys.

Every problem is collected in :class:`Problems` rather than raised, so that
``homing check`` lists them all in one pass.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from homing.missions.schema import (
    DEFAULT_RATE,
    DEFAULT_SERVICES,
    MAX_RATE,
    MIN_RATE,
    SUBTREE_KEYS,
    TOP_KEYS,
    suggest,
)

from homing import yamlfile
from homing.errors import UserError, UserErrors
from homing.yamlfile import LocatedDict, LocatedList

LIBRARY = Path(__file__).resolve().parent / "library"
Loc = tuple[int, int]


class Problems:
    """Errors collected in one pass, each ``file:line:col: message``, in order, without repeats."""

    def __init__(self) -> None:
        self.errors: list[UserError] = []
        self._seen: set[str] = set()

    def add(self, file: Path | str, loc: Loc, message: str) -> None:
        line, col = loc if loc and loc[0] > 0 else (1, 1)
        err = UserError(message, file, line, max(col, 1))
        if str(err) not in self._seen:
            self._seen.add(str(err))
            self.errors.append(err)

    def extend(self, err: UserError) -> None:
        if isinstance(err, UserErrors):
            for e in err.errors:
                self.extend(e)
            return
        loc = err.location
        self.add(loc.file if loc else "<mission>", (loc.line, loc.col) if loc else (1, 1), err.message)

    def __bool__(self) -> bool:
        return bool(self.errors)

    def raise_if_any(self) -> None:
        if self.errors:
            raise UserErrors(self.errors)


@dataclass
class Subtree:
    """A named tree with parameters (``None`` default = required), defined in ``file``."""

    name: str
    file: Path
    loc: Loc
    params: dict[str, Any]
    param_locs: dict[str, Loc]
    tree: Any
    tree_container: Any
    doc: str = ""


@dataclass
class ServiceUse:
    """One entry of ``services:``: the service's name, its parameters and where it was named."""

    name: str
    params: dict[str, Any]
    loc: Loc
    container: Any = None


@dataclass
class MissionSource:
    """A mission file with its includes read, before the registry is consulted."""

    path: Path
    name: str
    doc: str = ""
    rate: float = DEFAULT_RATE  # [Hz]
    services: list[ServiceUse] = field(default_factory=list)
    params: dict[str, Any] = field(default_factory=dict)
    param_locs: dict[str, Loc] = field(default_factory=dict)
    subtrees: dict[str, Subtree] = field(default_factory=dict)
    tree: Any = None
    tree_container: Any = None
    view_keys: list[str] = field(default_factory=list)
    files: list[Path] = field(default_factory=list)
    blackboard: dict[Any, Any] = field(default_factory=dict)  # initial entries, keys as written
    blackboard_locs: dict[Any, Loc] = field(default_factory=dict)


def _where(container: Any, key: Any, *, value: bool = True) -> Loc:
    loc = yamlfile.where(container, key, value=value)
    return loc if loc[0] > 0 else (1, 1)


def _read(path: Path, problems: Problems, at: tuple[Path, Loc] | None) -> LocatedDict | None:
    try:
        doc = yamlfile.load(path)
    except UserError as err:
        if at is not None and err.location is not None and err.location.line == 0:
            problems.add(at[0], at[1], f"cannot include '{path}': {err.message}")
        else:
            problems.extend(err)
        return None
    if doc is None:
        problems.add(path, (1, 1), "empty mission file (expected a mapping with 'tree:')")
        return None
    if not isinstance(doc, LocatedDict):
        problems.add(path, getattr(doc, "loc", (1, 1)), f"a mission file is a mapping of {', '.join(TOP_KEYS)}")
        return None
    for key in doc:
        if key not in TOP_KEYS:
            problems.add(path, _where(doc, key, value=False), f"unknown key '{key}'{suggest(key, TOP_KEYS)}")
    return doc


def _includes(doc: LocatedDict, path: Path, problems: Problems) -> list[tuple[Path, Loc]]:
    if "include" not in doc:
        return []
    raw = doc["include"]
    items: list[tuple[Any, Loc]]
    if isinstance(raw, str):
        items = [(raw, _where(doc, "include"))]
    elif isinstance(raw, LocatedList):
        items = [(v, _where(raw, i)) for i, v in enumerate(raw)]
    else:
        problems.add(path, _where(doc, "include"), "include: needs a path or a list of paths")
        return []
    out = []
    for value, loc in items:
        if not isinstance(value, str) or not value.strip():
            problems.add(path, loc, "include: entries are file paths")
            continue
        target = (path.parent / value).resolve()
        if not target.exists() and (LIBRARY / value).exists():
            target = (LIBRARY / value).resolve()
        if not target.exists():
            problems.add(path, loc, f"unknown include '{value}': no such file (looked beside {path.name} and in the library)")
            continue
        out.append((target, loc))
    return out


def _subtrees(doc: LocatedDict, path: Path, source: MissionSource, problems: Problems) -> None:
    if "subtrees" not in doc:
        return
    table = doc["subtrees"]
    if not isinstance(table, LocatedDict):
        problems.add(path, _where(doc, "subtrees"), "subtrees: needs a mapping of name: {params, tree}")
        return
    for name, body in table.items():
        key_loc = _where(table, name, value=False)
        if not isinstance(name, str) or not name.isidentifier():
            problems.add(path, key_loc, f"subtree name '{name}' must be an identifier (letters, digits, _)")
            continue
        if name in source.subtrees:
            other = source.subtrees[name]
            problems.add(path, key_loc, f"duplicate subtree '{name}' (also defined at {other.file}:{other.loc[0]}:{other.loc[1]})")
            continue
        if not isinstance(body, LocatedDict) or "tree" not in body:
            problems.add(path, _where(table, name), f"subtree '{name}' needs a mapping with 'tree:' (and optional 'params:')")
            continue
        for key in body:
            if key not in SUBTREE_KEYS:
                problems.add(path, _where(body, key, value=False), f"unknown key '{key}' in subtree '{name}'{suggest(key, SUBTREE_KEYS)}")
        params, locs = _param_table(body, path, problems, f"subtree '{name}'")
        source.subtrees[name] = Subtree(
            name, path, key_loc, params, locs, body["tree"], body, str(body.get("doc", "") or "")
        )


def _param_table(doc: LocatedDict, path: Path, problems: Problems, owner: str) -> tuple[dict[str, Any], dict[str, Loc]]:
    if "params" not in doc or doc["params"] is None:
        return {}, {}
    table = doc["params"]
    if not isinstance(table, LocatedDict):
        problems.add(path, _where(doc, "params"), f"params of {owner} need a mapping of name: default")
        return {}, {}
    params, locs = {}, {}
    for name, value in table.items():
        if not isinstance(name, str) or not name.isidentifier():
            problems.add(path, _where(table, name, value=False), f"parameter name '{name}' must be an identifier")
            continue
        params[name] = value
        locs[name] = _where(table, name, value=False)
    return params, locs


def _services(doc: LocatedDict, path: Path, problems: Problems) -> list[ServiceUse]:
    if "services" not in doc:
        return [ServiceUse(name, {}, _where(doc, "tree", value=False) if "tree" in doc else (1, 1)) for name in DEFAULT_SERVICES]
    raw = doc["services"]
    if raw is None:
        return []
    if not isinstance(raw, LocatedList):
        problems.add(path, _where(doc, "services"), "services: needs a list of service names")
        return []
    out = []
    for i, item in enumerate(raw):
        loc = _where(raw, i)
        if isinstance(item, str):
            out.append(ServiceUse(item, {}, loc))
        elif isinstance(item, LocatedDict) and len(item) == 1:
            name, params = next(iter(item.items()))
            if params is not None and not isinstance(params, LocatedDict):
                problems.add(path, _where(item, name), f"parameters of service '{name}' need a mapping")
                params = None
            out.append(ServiceUse(str(name), dict(params or {}), loc, params))
        else:
            problems.add(path, loc, "a service is a name or {name: {parameters}}")
    return out


BUNDLED = Path(__file__).resolve().parent  # the missions shipped with homing (explore.yaml, …)


def resolve_mission(path: str | Path) -> Path:
    """A mission file by path, or a bundled mission by bare name (``explore`` → ``explore.yaml``).

    A path that exists always wins, so a user's own ``explore.yaml`` is never
    shadowed; only a name with no folder and no file of that name falls back
    to the bundled missions (and their ``examples/``).
    """
    given = Path(path)
    if given.exists() or given.parent != Path("."):
        return given
    stem = given.name[:-5] if given.name.endswith(".yaml") else given.name
    for candidate in (BUNDLED / f"{stem}.yaml", BUNDLED / "examples" / f"{stem}.yaml"):
        if candidate.is_file():
            return candidate
    return given


def load_source(path: str | Path, overrides: dict[str, Any] | None = None, problems: Problems | None = None) -> MissionSource:
    """Read ``path`` and its includes. Problems go to ``problems`` (raised at the end if none was given)."""
    own = problems is None
    problems = problems if problems is not None else Problems()
    main = resolve_mission(path)
    source = MissionSource(path=main, name=main.stem)
    doc = _read(main, problems, None)
    if doc is not None:
        _top_level(doc, main, source, problems)
        _walk_includes(doc, main.resolve(), source, problems, [main.resolve()])
        _overrides(overrides or {}, source, problems)
    if own:
        problems.raise_if_any()
    return source


def _top_level(doc: LocatedDict, path: Path, source: MissionSource, problems: Problems) -> None:
    source.files.append(path)
    if "mission" in doc:
        source.name = str(doc["mission"])
    source.doc = str(doc.get("doc", "") or "")
    if "rate" in doc:
        rate = doc["rate"]
        if isinstance(rate, bool) or not isinstance(rate, (int, float)) or not MIN_RATE <= rate <= MAX_RATE:
            problems.add(path, _where(doc, "rate"), f"rate: needs a number of Hz in {MIN_RATE:g} … {MAX_RATE:g}, not {rate!r}")
        else:
            source.rate = float(rate)
    source.services = _services(doc, path, problems)
    source.params, source.param_locs = _param_table(doc, path, problems, "the mission")
    _subtrees(doc, path, source, problems)
    if "tree" not in doc or doc["tree"] is None:
        problems.add(path, doc.loc, "the mission has no 'tree:' (its root node)")
    else:
        source.tree, source.tree_container = doc["tree"], doc
    if "blackboard" in doc and doc["blackboard"] is not None:
        table = doc["blackboard"]
        if not isinstance(table, LocatedDict):
            problems.add(path, _where(doc, "blackboard"), "blackboard: needs a mapping of key: initial value")
        else:
            source.blackboard = dict(table)
            source.blackboard_locs = {k: _where(table, k, value=False) for k in table}
    view = doc.get("view")
    if view is not None:
        keys = view.get("blackboard") if isinstance(view, LocatedDict) else None
        if not isinstance(keys, LocatedList) or not all(isinstance(k, str) for k in keys):
            problems.add(path, _where(doc, "view"), "view: needs {blackboard: [keys to show]}")
        else:
            source.view_keys = list(keys)


def _walk_includes(doc: LocatedDict, path: Path, source: MissionSource, problems: Problems, chain: list[Path]) -> None:
    for target, loc in _includes(doc, path, problems):
        if target in chain:
            cycle = " → ".join(p.name for p in [*chain[chain.index(target):], target])
            problems.add(path, loc, f"include cycle: {cycle}")
            continue
        if target in source.files:
            continue  # included twice along different branches: read once
        child = _read(target, problems, (path, loc))
        if child is None:
            continue
        source.files.append(target)
        # An included file may be a whole mission; only its subtrees are used.
        _subtrees(child, target, source, problems)
        _walk_includes(child, target, source, problems, [*chain, target])


def _overrides(overrides: dict[str, Any], source: MissionSource, problems: Problems) -> None:
    for name, value in overrides.items():
        if name not in source.params:
            listing = ", ".join(f"{k}={v}" for k, v in source.params.items()) or "none"
            problems.add(source.path, (1, 1), f"--set {name}: the mission has no parameter '{name}'"
                         f"{suggest(name, source.params)} (its parameters: {listing})")
            continue
        source.params[name] = value

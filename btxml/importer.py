"""BehaviorTree.CPP / Nav2 XML → a homing mission, node by node through :mod:`homing.btxml.catalog`.

Every control node and decorator becomes its homing equivalent with its
counts and units converted (``msec`` → seconds, Nav2's battery fraction →
percent, ``number_of_retries`` kept as Nav2 counts it), every ``<SubTree>``
a homing subtree whose ports are its parameters (``goal="{target}"`` remaps,
a plain value fixes, an unmapped one stays the subtree's own entry, as
BT.CPP's isolated blackboards; ``_autoremap`` passes every entry through),
every ``{key}`` a blackboard port. A node homing cannot run is an error at
its ``file:line:col`` naming it and why; every error is collected and
reported at once. Attributes homing has no use for (a ROS server's name, a
plugin ID) are listed as notes, never dropped silently.

Entries the tree reads but never writes (Nav2's ``{goal}``, set by its
navigator) become the mission's ``blackboard:`` entries, each bound to a
mission parameter of the same name (``homing run … --set goal=[2, 1, 0]``),
so the imported mission passes ``homing check``.

A file written by ``homing export`` carries the mission's top level in a
header comment; its tags are homing's own node names, and the import
restores the mission exactly.
"""

from __future__ import annotations

import re
import tempfile
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import yaml
from homing.behaviours import load_nodes
from homing.behaviours.expression import ScriptSyntaxError, names, parse
from homing.behaviours.ports import parse_port
from homing.behaviours.registry import NODES, NodeSpec
from homing.btxml import catalog
from homing.btxml.reader import Document, Element, read
from homing.btxml.yaml_out import mission_text
from homing.missions.schema import suggest
from homing.robot import frames

from homing.errors import UserError, UserErrors

BOOLS = {"true": True, "false": False, "1": True, "0": False}
CALL_ATTRS = ("ID", "name", *catalog.GROOT_ATTRS)
HOMING_FRAMES = (frames.MAP, frames.ODOM, frames.BASE_LINK, frames.LASER, frames.CAMERA)  # REP-105, all always there


@dataclass
class Imported:
    """The result: the mission as data and YAML text, and the notes (ignored attributes, semantic differences)."""

    mission: dict[str, Any]
    text: str
    notes: list[str] = field(default_factory=list)


class Importer:
    """Converts one :class:`~homing.btxml.reader.Document`; problems are collected, then raised together."""

    def __init__(self, doc: Document):
        self.doc = doc
        self.errors: list[UserError] = []
        self.notes: list[str] = []
        self.homing_file = doc.header is not None
        self.tree_names = {tid: self._tree_name(tid) for tid in doc.trees}
        self.calls: list[tuple[str, str, dict[str, Any], bool]] = []  # (tree id, calling tree id, body, autoremap)
        self.names: dict[str, set[str]] = {}  # explicit node names used in each tree
        self.tree_keys: dict[str, set[str]] = {tid: set() for tid in doc.trees}
        self.watchers: list[dict[str, Any]] = []  # GoalUpdated-like bodies whose goal keys are Nav2's defaults
        self.current = ""

    # -- problems ------------------------------------------------------------------------
    def error(self, el: Element, message: str, attr: str | None = None) -> None:
        line, col = el.where(attr)
        self.errors.append(UserError(message, self.doc.file_of(self.current), line, col))

    def note(self, el: Element, message: str, attr: str | None = None) -> None:
        line, col = el.where(attr)
        self.notes.append(f"{self.doc.file_of(self.current).name}:{line}:{col}: {message}")

    def _tree_name(self, tree_id: str) -> str:
        name = re.sub(r"\W", "_", tree_id)
        name = name if name and not name[0].isdigit() else f"tree_{name}"
        return f"{name}_tree" if name in NODES else name

    # -- the whole document ------------------------------------------------------------------
    def convert(self) -> dict[str, Any]:
        header = dict(self.doc.header or {})
        trees: dict[str, Any] = {}
        for tree_id, element in self.doc.trees.items():
            self.current = tree_id
            trees[tree_id] = self.node(element.children[0])
        if self.errors:
            raise UserErrors(self.errors)
        mission: dict[str, Any] = {}
        if header:
            for key in ("mission", "doc", "rate", "services", "params", "blackboard", "include", "view"):
                if key in header:
                    mission[key] = header[key]
        else:
            mission["mission"] = self.doc.path.stem
        subtrees = {}
        subtree_info = header.get("subtrees", {}) if header else {}
        own = set(header.get("own_subtrees", self.doc.trees)) if header else set(self.doc.trees)
        params = self._subtree_params()
        for tree_id, tree in trees.items():
            if tree_id == self.doc.main or tree_id not in own:
                continue
            name = self.tree_names[tree_id]
            info = subtree_info.get(name, {})
            entry: dict[str, Any] = {}
            if info.get("doc"):
                entry["doc"] = info["doc"]
            declared = info.get("params", params.get(tree_id, {}))
            if declared:
                entry["params"] = declared
            entry["tree"] = tree
            subtrees[name] = entry
        if subtrees:
            mission["subtrees"] = subtrees
        mission["tree"] = trees[self.doc.main]
        return mission

    def _subtree_params(self) -> dict[str, dict[str, Any]]:
        """Each subtree's parameters: the ports its callers pass and its model declares; default: its own entry."""
        declared: dict[str, dict[str, Any]] = {tid: {} for tid in self.doc.trees}
        for tid in self.doc.trees:
            model = self.doc.models.get(tid)
            for port in model.children if model is not None and model.tag == "SubTree" else []:
                pname = port.attrs.get("name", "")
                if pname.isidentifier():
                    declared[tid][pname] = port.attrs.get("default", "{" + pname + "}")
        closure = self._autoremapped_keys()
        for tid, _caller, body, autoremap in self.calls:
            for key in body:
                if key != "name":
                    declared[tid].setdefault(key, "{" + key + "}")
            if autoremap:
                for key in sorted(closure[tid]):
                    declared[tid].setdefault(key, "{" + key + "}")
                    body.setdefault(key, "{" + key + "}")
        return declared

    def _autoremapped_keys(self) -> dict[str, set[str]]:
        keys = {tid: set(k) for tid, k in self.tree_keys.items()}
        changed = True
        while changed:  # a subtree that autoremaps an inner one passes the inner one's keys through too
            changed = False
            for tid, caller, _body, autoremap in self.calls:
                if autoremap and not keys[tid] <= keys[caller]:
                    keys[caller] |= keys[tid]
                    changed = True
        return keys

    # -- one node ----------------------------------------------------------------------------------
    def node(self, el: Element) -> Any:
        tag = el.tag
        if tag in ("Action", "Condition", "Control", "Decorator") and "ID" in el.attrs:
            tag = el.attrs["ID"]  # BT.CPP v3's explicit form
        for attr in el.attrs:
            if attr in catalog.PRE_POST_CONDITIONS:
                self.error(el, f"<{tag}>: the scripted {attr} condition has no homing equivalent yet "
                               "(put a ScriptCondition before the node)", attr)  # fmt: skip
        if tag in ("SubTree", "SubTreePlus"):
            return self.subtree_call(el, tag)
        if self.homing_file and tag in NODES:
            return self.direct(el, NODES[tag])
        rule = catalog.RULES.get(tag)
        if rule is None and tag not in NODES:
            spelt = {n.lower(): n for n in [*catalog.RULES, *catalog.NO_EQUIVALENT]}.get(tag.lower())
            if spelt is not None and spelt in catalog.RULES:
                self.note(el, f"<{tag}> read as BT.CPP's <{spelt}> (BT.CPP itself would not find '{tag}')")
                tag, rule = spelt, catalog.RULES[spelt]
        if rule is not None:
            unknown = [a for a in el.attrs if a not in (*rule.ports, *rule.ignore, *CALL_ATTRS)]
            if unknown and tag in NODES and all(NODES[tag].param(a) for a in unknown):
                return self.direct(el, NODES[tag])  # homing's own node of that name (a homing export, edited)
            return self.mapped(el, tag, rule)
        if tag in NODES:
            return self.direct(el, NODES[tag])
        if tag in catalog.NO_EQUIVALENT:
            self.error(el, f"<{tag}> has no homing equivalent: {catalog.NO_EQUIVALENT[tag]}")
        elif tag in self.doc.trees:
            self.error(el, f"<{tag}> names a <BehaviorTree>: call it with <SubTree ID=\"{tag}\"/>")
        else:
            known = [*catalog.RULES, *NODES]
            self.error(el, f"<{tag}> is neither a BT.CPP or Nav2 node homing knows nor a homing node{suggest(tag, known)}")
        return None

    def children(self, el: Element, spec: NodeSpec, tag: str) -> dict[str, Any] | None:
        kids = [self.node(c) for c in el.children]
        slots = spec.child_slots
        if not slots:
            if kids:
                self.error(el, f"<{tag}> is a leaf ({spec.name}) and takes no children, not {len(kids)}")
            return {}
        if slots == ("children",):
            if not kids:
                self.error(el, f"<{tag}> needs at least one child")
            return {"children": kids}
        need = [s for s in slots if s not in spec.optional]
        if not len(need) <= len(kids) <= len(slots):
            count = f"{len(need)}" if len(need) == len(slots) else f"{len(need)} to {len(slots)}"
            self.error(el, f"<{tag}> takes {count} children ({', '.join(slots)}), not {len(kids)}")
            return None
        return dict(zip(slots, kids, strict=False))

    def finish(self, el: Element, homing: str, body: dict[str, Any], kids: dict[str, Any] | None) -> Any:
        if "name" in el.attrs and (self.homing_file or el.attrs["name"] not in (el.tag, homing)):
            body = {"name": self.unique_name(el.attrs["name"]), **body}
        if kids is None:
            return None
        if list(kids) == ["children"] and not body:
            return {homing: kids["children"]}
        body = {**body, **kids}
        return {homing: body or None}

    def direct(self, el: Element, spec: NodeSpec) -> Any:
        """A homing node written in XML: attributes are its parameters, as YAML scalars."""
        body: dict[str, Any] = {}
        for attr, text in el.attrs.items():
            if attr in CALL_ATTRS:
                continue
            param = spec.param(attr)
            if param is None:
                known = [p.name for p in spec.params]
                self.error(el, f"<{el.tag}>: unknown parameter '{attr}' of {spec.name}{suggest(attr, known)}", attr)
                continue
            types = param.type if isinstance(param.type, tuple) else (param.type,)
            plain = types == (str,) or parse_port(text) is not None or text.startswith("$")
            body[attr] = text if plain else _yaml_text(text)
            self._record_keys(spec, attr, body[attr])
        return self.finish(el, spec.name, body, self.children(el, spec, el.tag))

    def unique_name(self, name: str) -> str:
        """BT.CPP lets names repeat; homing's explicit names are unique in a tree: the second is ``name#2``."""
        used = self.names.setdefault(self.current, set())
        unique, n = name, 1
        while unique in used:
            n += 1
            unique = f"{name}#{n}"
        used.add(unique)
        return unique

    def mapped(self, el: Element, tag: str, rule: catalog.Rule) -> Any:
        """A BT.CPP or Nav2 node through its catalog rule."""
        spec = NODES.get(rule.homing)
        if spec is None:
            self.error(el, f"<{tag}> maps to homing's '{rule.homing}', which is not registered here")
            return None
        if rule.note:
            self.note(el, f"<{tag}>: {rule.note}")
        body: dict[str, Any] = dict(rule.fixed)
        for attr, text in el.attrs.items():
            if attr in CALL_ATTRS:
                continue
            if attr in rule.ignore:
                self.note(el, f"<{tag}> {attr}='{text}' not used: {rule.ignore[attr]}", attr)
                continue
            if attr not in rule.ports:
                if tag.startswith("Switch") and re.fullmatch(r"case_\d+|variable", attr):
                    continue
                if rule.homing == "parallel" and attr in ("success_count", "failure_count", "success_threshold", "failure_threshold"):
                    continue
                self.error(el, f"<{tag}>: unknown port '{attr}'{suggest(attr, list(rule.ports))} "
                               f"(ports: {', '.join([*rule.ports, *rule.ignore]) or 'none'})", attr)  # fmt: skip
                continue
            param, conv = rule.ports[attr]
            value = self.value(el, attr, text, conv, tag)
            if value is not _BAD:
                body[param] = value
                self._record_keys(spec, param, value)
        if tag == "RoundRobin" and not BOOLS.get(el.attrs.get("wrap_around", "true").strip().lower(), False):
            self.error(el, "<RoundRobin wrap_around=\"false\">: homing's round_robin always wraps round to its first "
                           "child (Nav2's RoundRobin before the port); false is not supported", "wrap_around")  # fmt: skip
        if tag == "IsBatteryLow" and BOOLS.get(el.attrs.get("is_voltage", "false").lower(), False):
            self.error(el, "<IsBatteryLow is_voltage=\"true\">: homing's BatteryBelow compares percentages", "is_voltage")
        if tag == "TransformAvailable":
            for attr in ("child", "parent"):
                frame = el.attrs.get(attr, "").strip().lstrip("/")
                if frame not in HOMING_FRAMES:
                    self.error(el, f"<TransformAvailable {attr}=\"{frame}\">: homing's frames are "
                                   f"{', '.join(HOMING_FRAMES)}", attr)  # fmt: skip
        if rule.homing == "parallel":
            body.update(self.parallel(el))
        if rule.homing == "switch":
            body.update(self.switch(el, tag))
        watcher = False
        if rule.homing in ("GoalUpdated", "GlobalUpdatedGoal", "GoalUpdatedController") and not ({"goal", "goals"} & set(el.attrs)):
            body.update(goal_key="goal", goals_key="goals")  # Nav2 watches both by default
            watcher = True
        if rule.homing == "speed_controller" and "goal" not in el.attrs:
            body["goal_key"] = "goal"
            watcher = True
        if tag == "DockRobot":
            return self.dock_robot(el, body)
        order = [p.name for p in spec.params]
        body = dict(sorted(body.items(), key=lambda kv: order.index(kv[0]) if kv[0] in order else len(order)))
        node = self.finish(el, rule.homing, body, self.children(el, spec, tag))
        if watcher and isinstance(node, dict):
            self.watchers.append(node[rule.homing])
        return node

    def dock_robot(self, el: Element, body: dict[str, Any]) -> Any:
        """Nav2's DockRobot: homing's GoHome (unless navigate_to_staging_pose is false), then AutoDock."""
        dock = {"AutoDock": {k: v for k, v in body.items() if k == "failure_key"} or None}
        if not BOOLS.get(el.attrs.get("navigate_to_staging_pose", "true").lower(), True):
            return dock
        home = {k: v for k, v in body.items() if k in ("failure_key", "timeout")}
        name = self.unique_name(el.attrs.get("name", "DockRobot"))
        return {"sequence": {"name": name, "children": [{"GoHome": home or None}, dock]}}

    def value(self, el: Element, attr: str, text: str, conv: str, tag: str) -> Any:
        port = parse_port(text)
        if conv == "key":
            key = port.text if port is not None else text.strip()
            return attr if key == "=" else key
        if port is not None:
            if conv in ("ms", "abs", "fraction", "codes"):
                self.error(el, f"<{tag}> {attr}='{text}': a port read at run time cannot be converted "
                               f"({'milliseconds to seconds' if conv == 'ms' else conv}); give a value", attr)  # fmt: skip
                return _BAD
            return "{" + (attr if port.text == "=" else port.text) + "}"
        try:
            if conv == "bool":
                if text.strip().lower() not in BOOLS:
                    raise ValueError(f"expected true or false, not '{text}'")
                return BOOLS[text.strip().lower()]
            if conv == "int":
                return int(text)
            if conv in ("float", "ms", "abs", "fraction"):
                number = float(text)
                return {"float": number, "ms": number / 1000.0, "abs": abs(number),
                        "fraction": number * 100.0 if number <= 1.0 else number}[conv]
            if conv == "list":
                return [t for t in text.split(";") if t]
            if conv == "codes":
                return self.error_codes(el, attr, text, tag)
        except ValueError as err:
            self.error(el, f"<{tag}> {attr}='{text}': {err}", attr)
            return _BAD
        return _typed_text(text)

    def error_codes(self, el: Element, attr: str, text: str, tag: str) -> list[str]:
        """Nav2's numeric error codes (``a;b`` or ``a,b``) as homing's typed reasons; codes homing never reports are noted."""
        reasons: list[str] = []
        never: list[str] = []
        for token in re.split(r"[;,\s]+", text.strip()):
            if not token:
                continue
            code = int(token)
            if code in catalog.NAV2_ERROR_CODES:
                reason = catalog.NAV2_ERROR_CODES[code]
                if reason not in reasons:
                    reasons.append(reason)
            elif code in catalog.NAV2_ERRORS_NEVER_REPORTED:
                never.append(f"{code} ({catalog.NAV2_ERRORS_NEVER_REPORTED[code]})")
            else:
                raise ValueError(f"{code} is none of Nav2's controller (1xx), planner (2xx, 3xx) or smoother (5xx) "
                                 "error codes")
        if never:
            self.note(el, f"<{tag}> {attr}: homing never reports {', '.join(never)}", attr)
        return reasons

    def parallel(self, el: Element) -> dict[str, Any]:
        n = len(el.children)
        a = el.attrs
        success = int(a.get("success_count", a.get("success_threshold", "-1")))
        failure = int(a.get("failure_count", a.get("failure_threshold", "1")))
        success = n if success < 0 else success
        failure = n if failure < 0 else failure
        out: dict[str, Any] = {"success": "all" if success == n else success}
        if failure < n - success + 1:
            out["failure"] = failure
        return out

    def switch(self, el: Element, tag: str) -> dict[str, Any]:
        n = int(tag[len("Switch"):])
        if len(el.children) != n + 1:
            self.error(el, f"<{tag}> needs {n + 1} children ({n} cases and the default), not {len(el.children)}")
        variable = el.attrs.get("variable")
        if variable is None:
            self.error(el, f"<{tag}> needs variable=\"{{key}}\"")
            return {}
        port = parse_port(variable)
        key = port.text if port is not None else variable
        cases = [_typed_text(el.attrs.get(f"case_{i}", "")) for i in range(1, n + 1)]
        self.tree_keys[self.current].add(key)
        return {"key": key, "cases": cases}

    def subtree_call(self, el: Element, tag: str) -> Any:
        target = el.attrs.get("ID", "")
        if target not in self.doc.trees:
            self.error(el, f"<{tag} ID=\"{target}\">: no <BehaviorTree> with that ID{suggest(target, self.doc.trees)}", "ID")
            return None
        flags = ("_autoremap", "__autoremap", "__shared_blackboard")
        autoremap = any(BOOLS.get(el.attrs.get(f, "false").lower(), False) for f in flags)
        body: dict[str, Any] = {}
        if "name" in el.attrs:
            body["name"] = self.unique_name(el.attrs["name"])
        for attr, text in el.attrs.items():
            if attr in CALL_ATTRS:
                continue
            port = parse_port(text)
            if port is not None:
                body[attr] = "{" + (attr if port.text == "=" else port.text) + "}"
            else:
                body[attr] = _yaml_text(text) if self.homing_file else _typed_text(text)
            if port is not None:
                self.tree_keys[self.current].add(attr if port.text == "=" else port.text)
        self.calls.append((target, self.current, body, autoremap))
        return {self.tree_names[target]: body}

    # -- keys the tree uses (for autoremap and the mission's inputs) ------------------------------
    def _record_keys(self, spec: NodeSpec, param: str, value: Any) -> None:
        is_key = f"${param}" in (*spec.reads, *spec.writes)
        port = parse_port(value)
        if port is not None:
            self.tree_keys[self.current].add(port.text)
        elif is_key and isinstance(value, str) and value and not value.startswith("/"):
            self.tree_keys[self.current].add(value.lstrip("@"))
        if spec.name in ("Script", "ScriptCondition") and param == "code" and isinstance(value, str):
            self._record_script(value)

    def _record_script(self, code: str) -> None:
        try:
            reads, writes = names(parse(code))
        except ScriptSyntaxError:
            return  # homing check reports it at the node
        for n in [*reads, *writes]:
            text = n.text[1:-1].strip() if n.text.startswith("{") else n.text
            if not text.startswith("/"):
                self.tree_keys[self.current].add(text.lstrip("@"))


class _Bad:
    pass


_BAD: Any = _Bad()


def _yaml_text(text: str) -> Any:
    """An attribute written by ``homing export``: a YAML flow value (``5``, ``'5'``, ``[a, b]``, ``90 deg``)."""
    try:
        return yaml.safe_load(text)
    except yaml.YAMLError:
        return text


def _typed_text(text: str) -> Any:
    """An attribute's text as BT.CPP would convert it when read: a number or a bool if it is one, else the text."""
    stripped = text.strip()
    if stripped.lower() in ("true", "false"):
        return stripped.lower() == "true"
    for kind in (int, float):
        try:
            return kind(stripped)
        except ValueError:
            pass
    return text


def import_xml(path: str | Path, tree: str | None = None) -> Imported:
    """Convert a BT.CPP XML file (and the files it includes) to a homing mission, ``tree`` its main tree's ID.

    Raises :class:`UserErrors` listing every problem.
    """
    load_nodes()
    doc = read(path, tree)
    importer = Importer(doc)
    mission = importer.convert()
    if doc.header is None:
        _bind_inputs(mission, importer)
    slots = {s for spec in NODES.values() for s in spec.child_slots}
    comments = [] if doc.header is not None else [
        f"Imported from {doc.path.name} (BehaviorTree.CPP v{doc.format} XML) by 'homing import'.",
        *(["Entries the tree reads and nothing in it writes are mission parameters: give them with --set, "
           "e.g. --set goal=[2.0, 1.0, 0.0]"] if mission.get("blackboard") else []),
        *[f"note: {n}" for n in importer.notes],
    ]  # fmt: skip
    return Imported(mission, mission_text(mission, slots, comments), importer.notes)


def _unwritten(mission: dict[str, Any]) -> tuple[list[str], set[str]]:
    """(keys read and never written, keys read by anything but a goal watcher), as ``homing check`` sees them."""
    from homing.missions.compiler import Compiler
    from homing.missions.loader import Problems, load_source

    slots = {s for spec in NODES.values() for s in spec.child_slots}
    with tempfile.TemporaryDirectory() as tmp:
        probe = Path(tmp) / "probe.yaml"
        probe.write_text(mission_text(mission, slots))
        problems = Problems()
        compiler = Compiler(load_source(probe, None, problems), problems)
        compiler.compile()
    watchers = ("(GoalUpdated)", "(GlobalUpdatedGoal)", "(GoalUpdatedController)", "(speed_controller)")
    unwritten = sorted({r[0] for r in compiler.reads if r[0] not in compiler.writes})
    return unwritten, {r[0] for r in compiler.reads if not r[3].endswith(watchers)}


def _bind_inputs(mission: dict[str, Any], importer: Importer) -> None:
    """Entries read but never written become ``blackboard:`` entries bound to mission parameters.

    Nav2's goal watchers read both ``{goal}`` and ``{goals}`` by default; the
    one nothing else in the tree uses is dropped rather than made an input.
    """
    unwritten, readers = _unwritten(mission)
    # Nav2's navigators write {goal} or {goals} before the first tick: inputs, even if the tree rewrites them.
    unwritten = sorted(set(unwritten) | ({"/goal", "/goals"} & readers))
    unused = {"goal_key": "/goal" not in readers, "goals_key": "/goals" not in readers}
    if importer.watchers and any(unused.values()) and not all(unused.values()):
        for body in importer.watchers:
            for param, drop in unused.items():
                if drop and body.get(param) == param.split("_")[0]:
                    body[param] = ""
        unwritten, _ = _unwritten(mission)
        unwritten = sorted(set(unwritten) | ({"/goal", "/goals"} & readers))
    if not unwritten:
        return
    params = dict(mission.get("params") or {})
    board = dict(mission.get("blackboard") or {})
    for key in unwritten:
        name = re.sub(r"\W", "_", key.strip("/").replace("/", "_")) or "entry"
        params.setdefault(name, None)
        board[key if key.count("/") > 1 else key[1:]] = f"${name}"
    rebuilt = {k: v for k, v in mission.items() if k not in ("tree", "subtrees")}
    rebuilt["params"], rebuilt["blackboard"] = params, board
    for k in ("subtrees", "tree"):
        if k in mission:
            rebuilt[k] = mission[k]
    mission.clear()
    mission.update(rebuilt)

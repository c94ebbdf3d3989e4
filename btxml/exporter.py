"""A homing mission → BehaviorTree.CPP v4 XML with a ``TreeNodesModel``, so it opens in Groot2.

The mission is checked first (``homing check``'s compiler), then written
from its source, so subtrees stay ``<BehaviorTree>`` s called with
``<SubTree>`` and ``$parameters`` stay as written. A homing control node
whose BT.CPP or Nav2 namesake means exactly the same (``sequence`` is
BT.CPP's ``Sequence``, ``recovery`` Nav2's ``RecoveryNode`` with
``number_of_retries``, ``timeout`` BT.CPP's ``Timeout`` in whole
milliseconds) is written under that name; every other node under homing's
own name, declared in the ``TreeNodesModel`` with its ports, defaults and
docs. The mission's top level (services, parameters, blackboard entries,
rate) rides along in one comment, so ``homing import`` gives back the same
mission: YAML → XML → YAML is the identity on the tree.
"""

from __future__ import annotations

import json
import math
import xml.etree.ElementTree as ET
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import yaml
from homing.behaviours.ports import parse_port
from homing.behaviours.registry import NODES, NodeSpec, Param
from homing.btxml.reader import HEADER_TAG
from homing.btxml.yaml_out import scalar
from homing.missions.compiler import CompiledMission, compile_mission
from homing.missions.loader import MissionSource
from py_trees.behaviour import Behaviour

from homing import yamlfile

HEADER_KEYS = ("mission", "doc", "rate", "services", "params", "blackboard", "include", "view")
BTCPP_BUILTINS = {"Sequence", "ReactiveSequence", "SequenceWithMemory", "Fallback", "ReactiveFallback", "ParallelNode",
                  "IfThenElse", "WhileDoElse", "Inverter", "ForceSuccess", "ForceFailure", "KeepRunningUntilFailure",
                  "RunOnce", "Repeat", "RetryUntilSuccessful", "Timeout", "Delay", "SubTree",
                  *(f"Switch{n}" for n in range(2, 7))}  # fmt: skip
NAV2_MODELS = {"RecoveryNode": ("Control", ("number_of_retries",)), "RoundRobin": ("Control", ()),
               "PipelineSequence": ("Control", ()), "RateController": ("Decorator", ("hz",)),
               "DistanceController": ("Decorator", ("distance",)), "SingleTrigger": ("Decorator", ())}  # fmt: skip
SAME_NAME = {"reactive_sequence": "ReactiveSequence", "reactive_fallback": "ReactiveFallback",
             "sequence_with_memory": "SequenceWithMemory", "if_then_else": "IfThenElse",
             "while_do_else": "WhileDoElse", "inverter": "Inverter", "force_success": "ForceSuccess",
             "force_failure": "ForceFailure", "keep_running_until_failure": "KeepRunningUntilFailure",
             "round_robin": "RoundRobin", "pipeline_sequence": "PipelineSequence",
             "single_trigger": "SingleTrigger"}  # fmt: skip


def _plain(value: Any) -> Any:
    """YAML data (LocatedDict, LocatedList) as plain JSON-able data."""
    if isinstance(value, dict):
        return {str(k): _plain(v) for k, v in value.items()}
    if isinstance(value, list):
        return [_plain(v) for v in value]
    return value


def _ms(seconds: Any) -> str | None:
    """Whole milliseconds for a seconds value, or None when it has none (a unit string, a port, a fraction of a ms)."""
    if isinstance(seconds, bool) or not isinstance(seconds, (int, float)):
        return None
    ms = float(seconds) * 1000.0
    return str(int(round(ms))) if math.isclose(ms, round(ms), abs_tol=1e-9) and ms >= 0 else None


def _twin(kind: str, params: dict[str, Any], n_children: int) -> tuple[str, dict[str, str]] | None:
    """The BT.CPP / Nav2 namesake of a homing control node with these parameters, if it means exactly the same."""
    if kind in SAME_NAME and not params:
        return SAME_NAME[kind], {}
    if kind in ("sequence", "fallback") and params.get("memory", True) is True and set(params) <= {"memory"}:
        return kind.capitalize(), {}
    number = {"recovery": ("RecoveryNode", "retries", "number_of_retries"), "repeat": ("Repeat", "times", "num_cycles"),
              "retry": ("RetryUntilSuccessful", "attempts", "num_attempts")}  # fmt: skip
    if kind in number:
        tag, param, port = number[kind]
        value = params.get(param, 1 if kind == "recovery" else -1)
        if set(params) <= {param} and isinstance(value, int) and not isinstance(value, bool):
            return tag, {port: str(value)}
    if kind in ("timeout", "delay") and set(params) == {"seconds"} and _ms(params["seconds"]) is not None:
        return ("Timeout", {"msec": _ms(params["seconds"])}) if kind == "timeout" else ("Delay", {"delay_msec": _ms(params["seconds"])})  # type: ignore[dict-item]
    if kind == "run_once" and set(params) <= {"then_skip"} and isinstance(params.get("then_skip", True), bool):
        return "RunOnce", {"then_skip": str(params.get("then_skip", True)).lower()}
    single = {"rate_controller": ("RateController", "hz"), "distance_controller": ("DistanceController", "distance")}
    if kind in single and set(params) == {single[kind][1]}:
        value = params[single[kind][1]]
        if isinstance(value, (int, float)) and not isinstance(value, bool):
            return single[kind][0], {single[kind][1]: repr(float(value))}
    if kind == "parallel" and set(params) <= {"success", "failure"}:
        s, f = params.get("success", "all"), params.get("failure", "auto")
        if (s == "all" or isinstance(s, int)) and (f == "auto" or (isinstance(f, int) and f < n_children - (n_children if s == "all" else s) + 1)):
            attrs = {"success_count": "-1" if s == "all" else str(s)}
            attrs["failure_count"] = str(f) if f != "auto" else str(n_children - (n_children if s == "all" else s) + 1)
            return "ParallelNode", attrs
    return None


def _text(param: Param | None, value: Any) -> str:
    """A parameter value as attribute text that ``homing import`` reads back as the same value."""
    types = (param.type if isinstance(param.type, tuple) else (param.type,)) if param else (str,)
    if isinstance(value, str):
        if types == (str,) or parse_port(value) is not None or value.startswith("$"):
            return value
        try:
            same = yaml.safe_load(value) == value
        except yaml.YAMLError:
            same = False
        return value if same else scalar(value)
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, (int, float)):
        return repr(value)
    return scalar(_plain(value))


class Exporter:
    """Writes one compiled mission's source as BT.CPP v4 XML."""

    def __init__(self, source: MissionSource):
        self.source = source
        self.used: dict[str, NodeSpec] = {}
        self.twins: set[str] = set()

    def node(self, raw: Any) -> ET.Element:
        if isinstance(raw, str):
            kind, body = raw, None
        else:
            ((kind, body),) = raw.items()
        if kind in self.source.subtrees:
            attrs = {"ID": kind, **{str(k): _text(None, v) for k, v in (body or {}).items()}}
            return ET.Element("SubTree", attrs)
        spec = NODES[kind]
        slots = spec.child_slots
        if body is None:
            body = {}
        elif isinstance(body, list):
            body = {"children": body}
        elif not isinstance(body, dict):
            body = {next(p.name for p in spec.params if p.required): body}
        params = {str(k): v for k, v in body.items() if k != "name" and k not in slots}
        kids: list[Any] = []
        for slot in slots:
            if slot in body:
                kids.extend(body[slot] if slot == "children" else [body[slot]])
        twin = _twin(kind, params, len(kids))
        if twin is not None:
            tag, attrs = twin
            if tag in NAV2_MODELS:
                self.twins.add(tag)
        else:
            tag, attrs = kind, {k: _text(spec.param(k), v) for k, v in params.items() if v is not None}
            self.used[kind] = spec
        if "name" in body:
            attrs = {"name": str(body["name"]), **attrs}
        element = ET.Element(tag, attrs)
        element.extend(self.node(k) for k in kids)
        return element

    def models(self) -> ET.Element:
        models = ET.Element("TreeNodesModel")
        for kind, spec in sorted(self.used.items()):
            category = {"action": "Action", "condition": "Condition"}.get(spec.kind)
            if category is None:
                category = "Decorator" if spec.child_slots == ("child",) else "Control"
            model = ET.SubElement(models, category, {"ID": kind})
            for p in spec.params:
                attrs = {"name": p.name}
                if not p.required and p.default is not None:
                    attrs["default"] = _text(p, p.default)
                port = ET.SubElement(model, "input_port", attrs)
                port.text = (p.doc + (f" [{p.unit}]" if p.unit else "")) or None
        for tag in sorted(self.twins):
            category, ports = NAV2_MODELS[tag]
            model = ET.SubElement(models, category, {"ID": tag})
            for port_name in ports:
                ET.SubElement(model, "input_port", {"name": port_name})
        for name, sub in self.source.subtrees.items():
            model = ET.SubElement(models, "SubTree", {"ID": name})
            for pname, default in sub.params.items():
                attrs = {"name": pname}
                if default is not None:
                    attrs["default"] = _text(None, default)
                ET.SubElement(model, "input_port", attrs)
        return models


def export_xml(path: str | Path) -> str:
    """The mission at ``path`` as BT.CPP v4 XML text (the mission is checked first; mistakes raise UserErrors)."""
    mission = compile_mission(path)
    source = mission.source
    raw = yamlfile.load(source.path)
    header: dict[str, Any] = {key: _plain(raw[key]) for key in HEADER_KEYS if key in raw}
    header["subtrees"] = {name: {"params": _plain(sub.params), **({"doc": sub.doc} if sub.doc else {})}
                          for name, sub in source.subtrees.items()}  # fmt: skip
    header["own_subtrees"] = [name for name, sub in source.subtrees.items() if sub.file == source.path]
    exporter = Exporter(source)
    main_id = "MainTree" if "MainTree" not in source.subtrees else "MainTree_"
    root = ET.Element("root", {"BTCPP_format": "4", "main_tree_to_execute": main_id})
    text = json.dumps(header, ensure_ascii=False, separators=(", ", ": ")).replace("--", "-\\u002d")
    root.append(ET.Comment(f" {HEADER_TAG} {text} "))
    main = ET.SubElement(root, "BehaviorTree", {"ID": main_id})
    main.append(exporter.node(source.tree))
    for name, sub in source.subtrees.items():
        tree = ET.SubElement(root, "BehaviorTree", {"ID": name})
        tree.append(exporter.node(sub.tree))
    root.append(exporter.models())
    ET.indent(root, space="  ")
    return '<?xml version="1.0" encoding="UTF-8"?>\n' + ET.tostring(root, encoding="unicode") + "\n"


@dataclass
class LiveTree:
    """A compiled mission as BT.CPP writes a *running* tree (``WriteTreeToXML(tree, add_metadata=true, …)``).

    ``xml``: one ``<BehaviorTree ID _fullpath>`` per subtree instance (the
    main tree first, ``_fullpath=""``), every node with its ``name`` and a
    ``_uid`` (1, 2, … in preorder, as BT.CPP numbers nodes as it creates
    them), a ``<SubTree ID _fullpath _uid>`` where an instance is called,
    and the ``TreeNodesModel``. ``nodes``: ``(uid, behaviour)`` in the order
    ``Groot2Publisher`` lays out its status buffer (tree instance by tree
    instance as they were created, each one's nodes in uid order); homing compiles a subtree call into its instance's root, so a SubTree's
    uid shows that root's status, as BT.CPP's SubTree node mirrors its
    child. ``blackboards``: Groot2's blackboard names (the main tree's ID,
    each instance's ``_fullpath``) → the blackboard namespace its entries live
    under (``"/"``, ``"/<instance>/"``; ARCHITECTURE.md, blackboard keys).
    """

    xml: str
    nodes: list[tuple[int, Behaviour]] = field(default_factory=list)
    blackboards: dict[str, str] = field(default_factory=dict)


def _port_text(param: Param | None, value: Any) -> str:
    """A compiled parameter value as attribute text (``_text``), or its ``str`` when it has no YAML form."""
    try:
        return _text(param, value)
    except (yaml.YAMLError, TypeError, ValueError):
        return str(value)


def export_live(mission: CompiledMission) -> LiveTree:
    """The compiled ``mission`` as BT.CPP v4 XML with ``_uid`` attributes, for Groot2's monitor (see :class:`LiveTree`)."""
    source = mission.source
    exporter = Exporter(source)
    main_id = "MainTree" if "MainTree" not in source.subtrees else "MainTree_"
    root = ET.Element("root", {"BTCPP_format": "4", "main_tree_to_execute": main_id})
    live = LiveTree("", blackboards={main_id: "/"})
    trees: list[ET.Element] = [ET.Element("BehaviorTree", {"ID": main_id, "_fullpath": ""})]

    owner: dict[int, int] = {}  # uid → the index in `trees` of the tree instance holding the node

    def uid_for(node: Behaviour, tree: int) -> str:
        uid = len(live.nodes) + 1
        live.nodes.append((uid, node))
        owner[uid] = tree
        return str(uid)

    def element(node: Behaviour, tree: int, opened: int = 0) -> ET.Element:
        info = mission.info.get(node.id)
        instances = info.instances if info is not None else []
        if opened < len(instances):  # a subtree call compiled into this node: SubTree here, its tree apart
            tree_id, namespace = instances[opened]
            path = namespace.strip("/")
            call = ET.Element("SubTree", {"ID": tree_id, "_fullpath": path, "_uid": uid_for(node, tree)})
            trees.append(ET.Element("BehaviorTree", {"ID": tree_id, "_fullpath": path}))
            live.blackboards[path] = namespace
            inner = len(trees) - 1
            trees[inner].append(element(node, inner, opened + 1))
            return call
        attrs: dict[str, str] = {}
        if info is None:  # not built from the mission (none today): shown under its class name
            tag = type(node).__name__
        else:
            params = {k: ("{" + info.ports[k] + "}" if k in info.ports else v) for k, v in info.params.items()}
            twin = _twin(info.spec, params, len(node.children))
            if twin is not None:
                tag, attrs = twin
                if tag in NAV2_MODELS:
                    exporter.twins.add(tag)
            else:
                spec = NODES[info.spec]
                tag = info.spec
                attrs = {k: _port_text(spec.param(k), v) for k, v in params.items() if v is not None}
                exporter.used[info.spec] = spec
        out = ET.Element(tag, {"name": node.name, "_uid": uid_for(node, tree), **attrs})
        out.extend(element(child, tree) for child in node.children)
        return out

    trees[0].append(element(mission.root, 0))
    live.nodes.sort(key=lambda entry: (owner[entry[0]], entry[0]))
    root.extend(trees)
    root.append(exporter.models())
    ET.indent(root, space="  ")
    live.xml = '<?xml version="1.0" encoding="UTF-8"?>\n' + ET.tostring(root, encoding="unicode") + "\n"
    return live

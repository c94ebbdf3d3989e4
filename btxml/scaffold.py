"""``homing import … --scaffold DIR``: a plugin package of placeholder nodes for a BT.CPP project's custom nodes.

BT.CPP users register their own nodes in C++; homing cannot know them, so an
import stops at the first one. The scaffold writes, for every custom node the
trees use (a tag that is neither a BT.CPP or Nav2 node homing maps nor a
homing node), one class in a small installable package: its kind (action,
condition, decorator, control) and ports come from the file's
``<TreeNodesModel>`` when it declares the node — port direction, type and
default — or else are inferred from the uses (a leaf has no children, a
decorator one; a port's type is what its literal values parse as, any value
when only ``{key}`` is given). The classes derive from
:mod:`homing.behaviours.scaffold` and register through the entry-point group
``homing.behaviours``, so after ``pip install DIR`` the imported mission
passes ``homing check`` and runs; each leaf answers a fixed status (actions
and conditions SUCCESS) until its ``tick_leaf`` is filled in.
"""

from __future__ import annotations

import importlib
import re
import sys
from dataclasses import dataclass, field
from pathlib import Path

from homing.behaviours.registry import NODES
from homing.btxml import catalog
from homing.btxml.reader import Document, Element

from homing.errors import UserError

PORT_TAGS = {"input_port": "input", "output_port": "output", "inout_port": "inout"}
MODEL_KINDS = {"Action": "action", "Condition": "condition", "Decorator": "decorator", "Control": "control"}
CPP_TYPES = {"double": "float", "float": "float", "int": "int", "unsigned": "int", "long": "int", "bool": "bool",
             "std::string": "str", "string": "str", "BT::NodeStatus": "str"}  # fmt: skip
CONDITION_PREFIXES = ("Is", "Has", "Can", "Check", "Are", "Was", "Would")


@dataclass
class PortModel:
    """One port of a custom node: direction (input, output, inout), Python type name, default text, doc."""

    name: str
    direction: str = "input"
    type: str = ""
    default: str | None = None
    doc: str = ""
    values: list[str] = field(default_factory=list)  # literal (non-{key}) values seen in the uses


@dataclass
class NodeModel:
    """A custom node to scaffold: its BT.CPP ID, kind and ports, and whether the model declared it."""

    tag: str
    kind: str
    ports: dict[str, PortModel] = field(default_factory=dict)
    declared: bool = False


def custom_nodes(doc: Document) -> dict[str, NodeModel]:
    """The tags of the document's trees that homing knows under no name, with their models."""
    found: dict[str, NodeModel] = {}
    known = {n.lower() for n in [*catalog.RULES, *catalog.NO_EQUIVALENT]}

    def visit(el: Element) -> None:
        tag = el.attrs.get("ID", el.tag) if el.tag in MODEL_KINDS else el.tag
        custom = (tag not in ("SubTree", "SubTreePlus") and tag.lower() not in known and tag not in NODES
                  and tag not in doc.trees)  # fmt: skip
        if custom:
            node = found.get(tag) or _from_model(tag, doc.models.get(tag))
            found[tag] = node
            if not node.declared:
                node.kind = _kind_of(tag, el, node.kind)
            for attr, text in el.attrs.items():
                if attr in ("ID", "name", *catalog.GROOT_ATTRS, *catalog.PRE_POST_CONDITIONS):
                    continue
                port = node.ports.setdefault(attr, PortModel(attr))
                if not re.fullmatch(r"\s*\{.*\}\s*", text):
                    port.values.append(text)
        for child in el.children:
            visit(child)

    for element in doc.trees.values():
        visit(element.children[0])
    return found


def _from_model(tag: str, model: Element | None) -> NodeModel:
    if model is None or model.tag not in MODEL_KINDS:
        return NodeModel(tag, "")
    node = NodeModel(tag, MODEL_KINDS[model.tag], declared=True)
    for port in model.children:
        name = port.attrs.get("name", "")
        if port.tag in PORT_TAGS and name.isidentifier():
            cpp = port.attrs.get("type", "").strip()
            node.ports[name] = PortModel(name, PORT_TAGS[port.tag], CPP_TYPES.get(cpp, ""), port.attrs.get("default"),
                                         f"{PORT_TAGS[port.tag]} port" + (f" ({cpp})" if cpp else ""))  # fmt: skip
    return node


def _kind_of(tag: str, el: Element, seen: str) -> str:
    """A use's kind: a leaf (a condition when named like one), a decorator (one child) or a control node."""
    if seen == "control" or len(el.children) > 1:
        return "control"
    if el.children:
        return "decorator"
    if seen in ("action", "condition"):
        return seen
    return "condition" if re.match(r"(" + "|".join(CONDITION_PREFIXES) + r")[A-Z_]", tag) else "action"


def _type_of(port: PortModel) -> str:
    """The Python type of a port: the model's, else what every literal value parses as, else any value."""
    if port.type:
        return port.type
    if not port.values:
        return "VALUE_TYPES"
    texts = [v.strip() for v in port.values]
    if all(t.lower() in ("true", "false") for t in texts):
        return "bool"
    if all(re.fullmatch(r"[+-]?\d+", t) for t in texts):
        return "int"
    if all(re.fullmatch(r"[+-]?(\d+\.?\d*|\.\d+)([eE][+-]?\d+)?", t) for t in texts):
        return "float"
    return "str"


def _default(port: PortModel, kind: str) -> str:
    if port.default is None:
        return "None"
    text = port.default
    try:
        value: object = {"float": float, "int": int}[kind](text) if kind in ("float", "int") else text
    except ValueError:
        value = text
    if kind == "bool":
        value = text.strip().lower() == "true"
    return repr(value)


def package_name(source: Path) -> str:
    """The Python package a scaffold of ``source`` is written as: ``<stem>_nodes``, an identifier."""
    stem = re.sub(r"\W", "_", source.stem).strip("_").lower() or "tree"
    return f"{'_' + stem if stem[0].isdigit() else stem}_nodes"


def node_source(node: NodeModel, source: Path) -> str:
    """The Python class of one scaffolded node."""
    cls = re.sub(r"\W", "_", node.tag)
    cls = cls if cls and not cls[0].isdigit() else f"Node_{cls}"
    base = {"decorator": "ScaffoldDecorator", "control": "ScaffoldControl"}.get(node.kind, "ScaffoldLeaf")
    kind = {"control": "composite"}.get(node.kind, node.kind)
    lines = [f'@register("{node.tag}", kind="{kind}")', f"class {cls}({base}):",
             f'    """BT.CPP {node.kind} <{node.tag}> of {source.name}, scaffolded: '
             f'{"fill in tick_leaf" if base == "ScaffoldLeaf" else "fill in update"}.', "",
             f"    Ports {'from the file' + chr(39) + 's <TreeNodesModel>' if node.declared else 'inferred from the uses'}.",
             '    """', ""]  # fmt: skip
    params, outputs, defaults = [], [], []
    for port in node.ports.values():
        if port.direction == "output":
            params.append(f'        Param("{port.name}", str, "", doc="{port.doc or "output port"}: the key it writes"),')
            outputs.append(port.name)
            if port.default is not None:
                defaults.append(f"({port.name!r}, {port.default!r})")
            continue
        kind_name = _type_of(port)
        doc = port.doc or f"{port.direction} port"
        params.append(f'        Param("{port.name}", {kind_name}, {_default(port, kind_name)}, doc="{doc}"),')
    if params:
        lines += ["    PARAMS = (", *params, "    )"]
    if outputs and base == "ScaffoldLeaf":
        lines += [f"    OUTPUTS = {tuple(outputs)!r}", f"    WRITES = {tuple('$' + o for o in outputs)!r}"]
        if defaults:
            lines.append(f"    DEFAULTS = ({', '.join(defaults)},)")
    if base == "ScaffoldLeaf":
        lines += ["    STATUS = Status.SUCCESS", "", "    def tick_leaf(self) -> Status:",
                  "        # Fill in: read the input ports (self.<port>), write outputs with self.write(self.<output>, value).",
                  "        return super().tick_leaf()"]  # fmt: skip
    return "\n".join(lines).rstrip() + "\n"


def write_package(folder: Path, doc: Document, nodes: dict[str, NodeModel]) -> str:
    """Write the plugin package into ``folder`` and return its module (``<package>.nodes``)."""
    pkg = package_name(doc.path)
    module = folder / pkg / "nodes.py"
    if module.exists() and "scaffolded" not in module.read_text(errors="replace"):
        raise UserError("exists and is not a scaffold homing wrote: give another --scaffold folder", module)
    (folder / pkg).mkdir(parents=True, exist_ok=True)
    (folder / pkg / "__init__.py").write_text(f'"""Plugin nodes for {doc.path.name}, scaffolded by homing import."""\n')
    classes = [node_source(n, doc.path) for n in nodes.values()]
    body = "\n".join(classes)
    bases = sorted(b for b in ("ScaffoldControl", "ScaffoldDecorator", "ScaffoldLeaf") if f"({b})" in body)
    imports = [*(["from homing.behaviours.generic import VALUE_TYPES"] if "VALUE_TYPES" in body else []),
               f"from homing.behaviours.registry import {'Param, register' if 'Param(' in body else 'register'}",
               f"from homing.behaviours.scaffold import {', '.join(bases)}",
               *(["from py_trees.common import Status"] if "Status" in body else [])]  # fmt: skip
    header = [f'"""The custom nodes of {doc.path.name}, scaffolded by ``homing import --scaffold``: fill them in.',
              "", "Each class registers with homing when this module is imported (the entry point",
              '``homing.behaviours`` of this package does it after ``pip install``)."""', "",
              "from __future__ import annotations", "", *imports, "", "", ""]  # fmt: skip
    module.write_text("\n".join(header) + "\n\n".join(classes))
    (folder / "pyproject.toml").write_text(
        '[build-system]\nrequires = ["setuptools>=61"]\nbuild-backend = "setuptools.build_meta"\n\n'
        f'[project]\nname = "{pkg.replace("_", "-")}"\nversion = "0.1.0"\n'
        f'description = "homing plugin nodes for {doc.path.name} (scaffolded)"\ndependencies = ["homing"]\n\n'
        f'[project.entry-points."homing.behaviours"]\n{pkg} = "{pkg}.nodes"\n\n'
        f'[tool.setuptools]\npackages = ["{pkg}"]\n'
    )
    return f"{pkg}.nodes"


def register_now(folder: Path, module: str) -> None:
    """Import the written module so its nodes are registered in this process (the import then goes on)."""
    sys.path.insert(0, str(folder))
    try:
        importlib.invalidate_caches()
        importlib.import_module(module)
    finally:
        sys.path.remove(str(folder))


def scaffold(path: Path, tree: str | None, folder: Path) -> tuple[str, list[str]]:
    """Write the scaffold of ``path``'s custom nodes into ``folder`` and register them here: (module, node IDs)."""
    from homing.behaviours import load_nodes
    from homing.btxml.reader import read

    load_nodes()
    doc = read(path, tree)
    nodes = custom_nodes(doc)
    if not nodes:
        return "", []
    module = write_package(folder, doc, nodes)
    register_now(folder, module)
    return module, list(nodes)

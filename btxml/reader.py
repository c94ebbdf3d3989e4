"""Read BehaviorTree.CPP XML (v3 and v4, as Nav2 and Groot2 write it) safely, keeping every element's line:col.

The file goes through ``defusedxml``'s expat parser: entity declarations
(the "billion laughs"), external entities and DTD-fetched content are
refused with a one-line error instead of being expanded, and the file's size,
element count and nesting depth are bounded before anything is built.
Positions come from expat itself while it parses (the start of each
element's tag); an attribute's position is found in the tag's text, so an
importer can point at ``file:line:col`` of the very attribute it rejects.

A project split over many files is read as BehaviorTree.CPP's XMLParser
reads it: every ``<include path="…"/>`` of a file is loaded first, its path
relative to the directory of the file that includes it (so a child file
reaches its parent's sibling with ``../``), recursively; the trees of all the
files are registered together, and the main tree is the first file's
``main_tree_to_execute`` (or the only tree). homing refuses what BT.CPP would
loop on or overwrite silently: an include cycle, a missing file and a tree ID
defined twice are ``file:line:col`` errors at the offending element.
``ros_pkg`` includes need ROS's package index and are refused.

The result is a :class:`Document`: the format (3 or 4), the main tree's ID,
every ``<BehaviorTree>`` by ID (and the file it came from), the
``<TreeNodesModel>`` entries, and the homing header (the comment ``homing
export`` writes) when there is one.
"""

from __future__ import annotations

import json
import re
import xml.etree.ElementTree as ET
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from defusedxml import DefusedXmlException
from defusedxml.ElementTree import DefusedXMLParser

from homing.errors import UserError

MAX_BYTES = 4 * 1024 * 1024  # a navigator tree is a few kB; Groot2 projects stay well under this
MAX_ELEMENTS = 50_000
MAX_DEPTH = 256
HEADER_TAG = "homing-mission:"  # the comment homing export writes: JSON of the mission's top level


@dataclass
class Element:
    """One XML element: tag, attributes (in order), children, and where it starts (1-based line, column)."""

    tag: str
    attrs: dict[str, str]
    line: int
    col: int
    children: list[Element] = field(default_factory=list)
    attr_pos: dict[str, tuple[int, int]] = field(default_factory=dict)

    def where(self, attr: str | None = None) -> tuple[int, int]:
        """(line, col) of the element, or of one of its attributes."""
        return self.attr_pos.get(attr, (self.line, self.col)) if attr else (self.line, self.col)


@dataclass
class Document:
    """A BT.CPP XML file: its trees by ID, which one is the main tree, the node models, and a homing header."""

    path: Path
    format: int
    main: str
    trees: dict[str, Element]
    models: dict[str, Element]
    header: dict[str, Any] | None
    root: Element
    files: dict[str, Path] = field(default_factory=dict)  # tree ID -> the file that defines it

    def file_of(self, tree_id: str) -> Path:
        """The file a tree was read from (the first file when it is not an included one)."""
        return self.files.get(tree_id, self.path)


class _Builder:
    """expat target that builds :class:`Element` s with positions and keeps comments."""

    def __init__(self, text: str, raw: bytes, path: Path):
        self.text, self.raw, self.path = text, raw, path
        self.parser: Any = None
        self.stack: list[Element] = []
        self.top: Element | None = None
        self.count = 0
        self.comments: list[str] = []
        self.line_starts = [0] + [m.end() for m in re.finditer("\n", text)]

    def _position(self, char: int) -> tuple[int, int]:
        lo, hi = 0, len(self.line_starts) - 1
        while lo < hi:
            mid = (lo + hi + 1) // 2
            if self.line_starts[mid] <= char:
                lo = mid
            else:
                hi = mid - 1
        return lo + 1, char - self.line_starts[lo] + 1

    def start(self, tag: str, attrs: dict[str, str]) -> None:
        self.count += 1
        if self.count > MAX_ELEMENTS or len(self.stack) >= MAX_DEPTH:
            what = f"more than {MAX_ELEMENTS} elements" if self.count > MAX_ELEMENTS else f"nested deeper than {MAX_DEPTH}"
            raise UserError(f"refused: {what} (a behaviour tree file is far smaller)", self.path,
                            self.parser.CurrentLineNumber, self.parser.CurrentColumnNumber + 1)  # fmt: skip
        char = len(self.raw[: self.parser.CurrentByteIndex].decode("utf-8", errors="replace"))
        line, col = self._position(char)
        element = Element(tag, dict(attrs), line, col)
        end = self.text.find(">", char)
        tag_text = self.text[char : end if end >= 0 else len(self.text)]
        for name in attrs:
            m = re.search(r"\s" + re.escape(name) + r"\s*=", tag_text)
            if m is not None:
                element.attr_pos[name] = self._position(char + m.start() + 1)
        if self.stack:
            self.stack[-1].children.append(element)
        else:
            self.top = element
        self.stack.append(element)

    def end(self, tag: str) -> None:
        self.stack.pop()

    def data(self, data: str) -> None:
        pass

    def comment(self, text: str) -> None:
        self.comments.append(text)

    def close(self) -> Element | None:
        return self.top


def parse(path: str | Path) -> tuple[Element, list[str]]:
    """The root element and the comments of an XML file; every problem is a :class:`UserError` at its place."""
    p = Path(path)
    try:
        size = p.stat().st_size
        if size > MAX_BYTES:
            raise UserError(f"refused: {size} bytes is more than the {MAX_BYTES} a behaviour tree file may have", p)
        raw = p.read_bytes()
    except FileNotFoundError:
        raise UserError("no such file", p) from None
    except IsADirectoryError:
        raise UserError("is a directory, not an XML file", p) from None
    except OSError as err:
        raise UserError(f"cannot read: {err.strerror}", p) from None
    try:
        text = raw.decode("utf-8")
    except UnicodeDecodeError as err:
        raise UserError(f"not UTF-8 text (byte {err.start})", p) from None
    builder = _Builder(text, raw, p)
    parser = DefusedXMLParser(target=builder, forbid_dtd=False, forbid_entities=True, forbid_external=True)
    builder.parser = parser.parser
    try:
        parser.feed(raw)
        root = parser.close()
    except DefusedXmlException as err:
        line, col = builder.parser.CurrentLineNumber, builder.parser.CurrentColumnNumber + 1
        kind = type(err).__name__.replace("Forbidden", "").lower() or "construct"
        raise UserError(f"refused: the file declares {_article(kind)} (entity expansion and external "
                        "references are not read, for safety)", p, line, col) from None  # fmt: skip
    except ET.ParseError as err:
        line, col = err.position
        message = str(err).split(":")[0]
        raise UserError(f"not well-formed XML: {message}", p, line, col + 1) from None
    if root is None:
        raise UserError("empty XML file", p)
    return root, builder.comments


def _article(kind: str) -> str:
    return {"entities": "an entity", "dtd": "a DTD", "externalreference": "an external reference"}.get(kind, kind)


def read(path: str | Path, tree: str | None = None) -> Document:
    """Read a BT.CPP XML file and the files it includes into a :class:`Document`.

    ``tree`` picks the main tree by ID (``homing import --tree``); without it
    the first file's ``main_tree_to_execute`` does, or the only tree there is.
    """
    p = Path(path)
    project = _Project()
    root, comments = project.load(p, [])
    fmt_text = root.attrs.get("BTCPP_format", "3")
    if not project.trees:
        raise UserError("no <BehaviorTree> in the file", p, root.line, root.col)
    trees = {tid: el for tid, (el, _) in project.trees.items()}
    files = {tid: f for tid, (_, f) in project.trees.items()}
    main = tree or root.attrs.get("main_tree_to_execute", "")
    if tree is not None and tree not in trees:
        raise UserError(f"--tree {tree}: no <BehaviorTree> with that ID (there are: {', '.join(trees)})", p)
    if not main:
        if len(trees) > 1:
            raise UserError(f"several trees and no main_tree_to_execute: pick one with --tree ({', '.join(trees)})",
                            p, root.line, root.col)  # fmt: skip
        main = next(iter(trees))
    if main not in trees:
        line, col = root.where("main_tree_to_execute")
        raise UserError(f"main_tree_to_execute='{main}' names no <BehaviorTree> (there are: {', '.join(trees)})", p, line, col)
    return Document(p, int(fmt_text), main, trees, project.models, _header(comments, p), root, files)


class _Project:
    """The files of one BT.CPP project, loaded include by include as BT.CPP's XMLParser does."""

    def __init__(self) -> None:
        self.trees: dict[str, tuple[Element, Path]] = {}
        self.models: dict[str, Element] = {}
        self.loaded: set[Path] = set()

    def load(self, p: Path, chain: list[Path]) -> tuple[Element, list[str]]:
        """Read one file (after the files it includes); ``chain`` is the files including it, outermost first."""
        root, comments = parse(p)
        self.loaded.add(p.resolve())
        if root.tag != "root":
            raise UserError(f"expected <root> (a BehaviorTree.CPP file), found <{root.tag}>", p, root.line, root.col)
        fmt_text = root.attrs.get("BTCPP_format", "3")
        if fmt_text not in ("3", "4"):
            line, col = root.where("BTCPP_format")
            raise UserError(f"BTCPP_format '{fmt_text}': homing reads formats 3 and 4", p, line, col)
        for child in root.children:
            if child.tag == "include":
                self.include(p, child, [*chain, p])
        several = len([c for c in root.children if c.tag == "BehaviorTree"]) > 1
        for child in root.children:
            if child.tag == "BehaviorTree":
                self.tree(p, child, several)
            elif child.tag == "TreeNodesModel":
                for model in child.children:
                    if "ID" in model.attrs:
                        self.models[model.attrs["ID"]] = model
            elif child.tag != "include":
                raise UserError(f"unexpected <{child.tag}> in <root> (expected <BehaviorTree>, <TreeNodesModel> "
                                "or <include>)", p, child.line, child.col)  # fmt: skip
        return root, comments

    def include(self, p: Path, el: Element, chain: list[Path]) -> None:
        """Follow ``<include path="…"/>``, relative to the including file's directory."""
        if "ros_pkg" in el.attrs:
            raise UserError("<include ros_pkg=…> needs ROS's package index: give a path relative to this file",
                            p, *el.where("ros_pkg"))  # fmt: skip
        text = el.attrs.get("path", "").strip()
        if not text:
            raise UserError("<include> needs a path=\"…\" attribute", p, el.line, el.col)
        target = Path(text) if Path(text).is_absolute() else p.parent / text
        line, col = el.where("path")
        resolved = target.resolve()
        names = [c.resolve() for c in chain]
        if resolved in names:
            cycle = " -> ".join(str(c) for c in chain[names.index(resolved):])
            raise UserError(f"include cycle: {cycle} -> {target}", p, line, col)
        if resolved in self.loaded:
            return  # included twice (a diamond): its trees are registered already
        if not target.is_file():
            what = "is a directory, not an XML file" if target.is_dir() else "no such file"
            raise UserError(f"<include path=\"{text}\">: {what} ({target})", p, line, col)
        self.load(target, chain)

    def tree(self, p: Path, child: Element, several: bool) -> None:
        tree_id = child.attrs.get("ID", "")
        if not tree_id and several:
            raise UserError("<BehaviorTree> needs an ID when there are several", p, child.line, child.col)
        tree_id = tree_id or "MainTree"
        if tree_id in self.trees:
            first_el, first_file = self.trees[tree_id]
            raise UserError(f"duplicate <BehaviorTree ID=\"{tree_id}\"> (first at {first_file}:{first_el.line}:"
                            f"{first_el.col})", p, *child.where("ID"))  # fmt: skip
        if len(child.children) != 1:
            raise UserError(f"<BehaviorTree ID=\"{tree_id}\"> needs exactly one root node, not {len(child.children)}",
                            p, child.line, child.col)  # fmt: skip
        self.trees[tree_id] = (child, p)


def _header(comments: list[str], path: Path) -> dict[str, Any] | None:
    for text in comments:
        body = text.strip()
        if body.startswith(HEADER_TAG):
            try:
                header = json.loads(body[len(HEADER_TAG):])
            except json.JSONDecodeError as err:
                raise UserError(f"the homing header comment is not valid JSON: {err.msg}", path) from None
            if not isinstance(header, dict):
                raise UserError("the homing header comment must hold a JSON object", path)
            return header
    return None

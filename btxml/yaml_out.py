"""Write a mission (plain Python data) as YAML a person would write: control nodes as blocks, leaves on one line.

``yaml.safe_dump`` would put every mapping in block style or every one in
flow style; a mission reads best with composites and decorators as indented
blocks and each leaf's parameters as a one-line flow mapping, as the bundled
missions are written. Scalars go through ``safe_dump`` so they come back the
same (``"{goal}"`` is quoted, ``5`` stays a number, ``'5'`` a string).
"""

from __future__ import annotations

from typing import Any

import yaml

SLOT_KEYS = ("child", "children")


def scalar(value: Any) -> str:
    """One value in flow style (a scalar, or a list or mapping on one line)."""
    text = yaml.safe_dump(value, default_flow_style=True, width=10**9, allow_unicode=True, sort_keys=False)
    if text.endswith("\n...\n"):  # a plain scalar document ends with an explicit end marker
        text = text[: -len("\n...\n")]
    return text.strip()


def _is_node_body_with_children(body: Any, slots: set[str]) -> bool:
    return isinstance(body, dict) and any(k in slots for k in body)


def node_lines(node: Any, indent: int, slots: set[str]) -> list[str]:
    """``node`` ({kind: body} or a bare kind) as lines at ``indent`` spaces; ``slots`` are the child-holding keys."""
    pad = " " * indent
    if isinstance(node, str):
        return [pad + scalar(node)]
    (kind, body), = node.items()
    if body is None:
        return [pad + scalar(kind)]
    if isinstance(body, list):  # a composite given as its children
        return [f"{pad}{scalar(kind)}:", *list_lines(body, indent + 2, slots)]
    if not _is_node_body_with_children(body, slots):
        return [f"{pad}{scalar(kind)}: {scalar(body)}"]
    out = [f"{pad}{scalar(kind)}:"]
    for key, value in body.items():
        if key == "children":
            out.append(f"{pad}  children:")
            out.extend(list_lines(value, indent + 4, slots))
        elif key in slots:
            out.append(f"{pad}  {scalar(key)}:")
            out.extend(node_lines(value, indent + 4, slots))
        else:
            out.append(f"{pad}  {scalar(key)}: {scalar(value)}")
    return out


def list_lines(items: list[Any], indent: int, slots: set[str]) -> list[str]:
    out = []
    for item in items:
        lines = node_lines(item, indent + 2, slots)
        out.append(" " * indent + "- " + lines[0].lstrip())
        out.extend(lines[1:])
    return out


def mission_text(mission: dict[str, Any], slots: set[str], comments: list[str] = ()) -> str:  # type: ignore[assignment]
    """The whole mission file: ``comments`` as ``#`` lines, then the top-level keys in order."""
    out = [f"# {line}" if line else "#" for line in comments]
    for key, value in mission.items():
        if key == "tree":
            out.append("tree:")
            out.extend(node_lines(value, 2, slots))
        elif key == "subtrees":
            out.append("subtrees:")
            for name, sub in value.items():
                out.append(f"  {scalar(name)}:")
                for k, v in sub.items():
                    if k == "tree":
                        out.append("    tree:")
                        out.extend(node_lines(v, 6, slots))
                    else:
                        out.append(f"    {scalar(k)}: {scalar(v)}")
        else:
            out.append(f"{scalar(key)}: {scalar(value)}")
    return "\n".join(out) + "\n"

"""Behaviours: thin py_trees leaves and decorators over the modules, through the blackboard.

Every module in this package registers its nodes when imported
(:func:`homing.behaviours.registry.register`). :func:`load_nodes` imports them
all, plus third-party modules named by entry points of the group
``homing.behaviours``, so that a new module appears in missions, ``homing
nodes`` and ``homing check`` without editing any shared list.
"""

from __future__ import annotations

import importlib
import pkgutil
from importlib import metadata

ENTRY_POINT_GROUP = "homing.behaviours"

_loaded = False
_problems: list[str] = []


def load_nodes(*, entry_points: bool = True) -> list[str]:
    """Import every module under ``homing.behaviours`` and every entry point of the group.

    Returns the problems met (a module that fails to import, an entry point
    that cannot load) as one-line strings instead of raising, so that a
    half-written module of one engineer does not stop everyone's missions;
    ``homing nodes`` and ``homing check`` print them. Idempotent: the second
    call only returns the first call's problems.
    """
    global _loaded
    if _loaded:
        return list(_problems)
    _loaded = True
    for info in sorted(pkgutil.walk_packages(__path__, prefix=f"{__name__}."), key=lambda m: m.name):
        if info.name.rsplit(".", 1)[-1].startswith("_"):
            continue
        try:
            importlib.import_module(info.name)
        except Exception as err:  # a broken leaf module must not break every mission
            _problems.append(f"cannot import {info.name}: {type(err).__name__}: {err}")
    if entry_points:
        for ep in _entry_points():
            try:
                target = ep.load()
                if callable(target) and not isinstance(target, type):
                    target()
            except Exception as err:
                _problems.append(f"cannot load entry point {ep.name} = {ep.value}: {type(err).__name__}: {err}")
    return list(_problems)


def _entry_points() -> list[metadata.EntryPoint]:
    return sorted(metadata.entry_points(group=ENTRY_POINT_GROUP), key=lambda ep: ep.name)

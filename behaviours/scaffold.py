"""Base classes of the plugin nodes ``homing import --scaffold`` writes for a BT.CPP project's custom nodes.

A scaffolded node is a class in the user's own package, registered through
the entry-point group ``homing.behaviours`` like any third-party leaf: it
declares its BT.CPP ports as parameters (input ports are ordinary
parameters, so ``"{key}"`` reads them from the blackboard when the node
starts; output ports are key parameters the node writes), and answers a
fixed status until the user fills in :meth:`ScaffoldLeaf.tick_leaf`.

Use them only as the starting point of a port from BT.CPP: a finished leaf
should follow :class:`~homing.behaviours.base.HomingBehaviour`'s lifecycle
and call a module, not hold an algorithm.
"""

from __future__ import annotations

from collections.abc import Iterable
from typing import Any, ClassVar

import py_trees
from homing.behaviours.base import HomingBehaviour
from py_trees.common import Access, Status


class ScaffoldLeaf(HomingBehaviour):
    """A custom BT.CPP action or condition, not written yet: answers ``STATUS`` and writes its outputs' defaults.

    ``PARAMS`` lists every port (an output port is a parameter naming the key
    it writes, listed in ``OUTPUTS``; ``DEFAULTS`` gives the value written
    there until the node computes one — BT.CPP's model default, if any).
    """

    OUTPUTS: ClassVar[tuple[str, ...]] = ()
    DEFAULTS: ClassVar[tuple[tuple[str, Any], ...]] = ()  # (output port, value written) pairs
    STATUS: ClassVar[Status] = Status.SUCCESS

    def __init__(self, name: str, **params: Any) -> None:
        for param in self.PARAMS:
            setattr(self, param.name, params.get(param.name, param.default))
        super().__init__(name)
        for out in self.OUTPUTS:
            if getattr(self, out):
                self.bb.register_key(key=getattr(self, out), access=Access.WRITE)

    def _keys(self, keys: Iterable[str]) -> list[str]:
        return [k for k in super()._keys(keys) if k and k != "None"]  # an output port left unconnected

    def tick_leaf(self) -> Status:
        """Fill in: do the node's work (read ``self.<port>``, write outputs with ``self.write``)."""
        for out, value in self.DEFAULTS:
            if getattr(self, out):
                self.write(getattr(self, out), value)
        return self.STATUS

    def update(self) -> Status:
        status = self.tick_leaf()
        self.feedback_message = f"scaffold of BT.CPP <{type(self).__name__}>: {status.value} until filled in"
        return status


class ScaffoldDecorator(py_trees.decorators.Decorator):
    """A custom BT.CPP decorator, not written yet: passes its child's status through."""

    def __init__(self, name: str, child: py_trees.behaviour.Behaviour, **params: Any) -> None:
        super().__init__(name=name, child=child)
        for key, value in params.items():
            setattr(self, key, value)

    def update(self) -> Status:
        self.feedback_message = f"scaffold of BT.CPP <{type(self).__name__}>: passes its child's status"
        return self.decorated.status


class ScaffoldControl(py_trees.composites.Sequence):
    """A custom BT.CPP control node, not written yet: a sequence with memory (BT.CPP's ``Sequence``)."""

    def __init__(self, name: str, children: list[py_trees.behaviour.Behaviour], **params: Any) -> None:
        super().__init__(name=name, memory=True, children=children)
        for key, value in params.items():
            setattr(self, key, value)

"""``Script`` and ``ScriptCondition``: leaves that run a small expression over blackboard values (BT.CPP v4's).

The language is :mod:`homing.behaviours.expression` (comparisons,
arithmetic, assignment; no ``eval``). The compiler parses a script before
the first tick, so a syntax error is a ``file:line:col`` error of
``homing check``, and it resolves every name to a blackboard key the way it
resolves a port, so ``homing check`` proves that what a script reads is
written somewhere (an assignment ``x := …`` writes ``x``).
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any, ClassVar

from homing.behaviours.base import HomingBehaviour
from homing.behaviours.expression import Evaluator, Name, ScriptError, names, parse
from homing.behaviours.registry import REQUIRED, Param, register
from py_trees.common import Access, Status


def default_key(text: str) -> str:
    """The key a name stands for at the top of a mission: ``x`` → ``/x``, ``@x`` → ``/x``, ``{/a/b}`` → ``/a/b``."""
    if text.startswith("{"):
        text = text[1:-1].strip()
    text = text.lstrip("@")
    return text if text.startswith("/") else "/" + text


class _Scripted(HomingBehaviour):
    """Parses ``code`` and evaluates it against the blackboard; subclasses turn the value into a status."""

    PARAMS: ClassVar[tuple[Param, ...]] = (Param("code", str, REQUIRED, doc="statements separated by ';'"),)

    def __init__(self, name: str, code: str, keys: dict[str, Any] | None = None):
        super().__init__(name)
        self.code = code
        self.statements = parse(code)
        self.keys = dict(keys) if keys is not None else {}
        reads, writes = names(self.statements)
        for n in reads:
            self._register(n, Access.READ)
        for n in writes:
            self._register(n, Access.WRITE)
        self.evaluator = Evaluator(self.key_of, self.bb.get, self._set)

    def _set(self, key: str, value: Any) -> None:
        self.bb.set(key, value, overwrite=True)

    def key_of(self, name: Name) -> Any:
        """The absolute key (or the fixed value) ``name`` stands for."""
        return self.keys.get(name.text, default_key(name.text))

    def _register(self, name: Name, access: Access) -> None:
        where = self.key_of(name)
        if isinstance(where, str):
            self.bb.register_key(key=where, access=access)

    @classmethod
    def compile_keys(cls, params: dict[str, Any], resolve: Callable[[str], Any]) -> tuple[dict[str, Any], tuple[str, ...], tuple[str, ...]]:
        """For the compiler: (extra constructor arguments, keys read, keys written) given a name resolver.

        ``resolve(text)`` turns a name as written into an absolute key, or a
        :class:`~homing.behaviours.expression.Const` for a subtree parameter
        fixed to a value. Raises :class:`~homing.behaviours.expression.ScriptSyntaxError`.
        """
        statements = parse(params["code"])
        reads, writes = names(statements)
        keys = {n.text: resolve(n.text) for n in [*reads, *writes]}
        read_keys = tuple(dict.fromkeys(keys[n.text] for n in reads if isinstance(keys[n.text], str)))
        write_keys = tuple(dict.fromkeys(keys[n.text] for n in writes if isinstance(keys[n.text], str)))
        return {"keys": keys}, read_keys, write_keys

    def evaluate(self) -> tuple[bool, Any]:
        """(ran, value): the script's value, or (False, None) with the reason in the feedback message."""
        try:
            value = self.evaluator.run(self.statements)
        except ScriptError as err:
            self.feedback_message = str(err)
            return False, None
        self.feedback_message = f"{self.code} → {value!r}"
        return True, value


@register("Script")
class Script(_Scripted):
    """Run ``code`` (assignments, arithmetic) on the blackboard and SUCCEED; FAILURE if it cannot run: BT.CPP ``Script``.

    ``Script: {code: "laps := laps + 1"}``. One tick; never RUNNING. An
    entry that is read but unset, a type mismatch or a division by zero
    fails the leaf with the reason as its feedback (BT.CPP throws).
    """

    def update(self) -> Status:
        ran, _ = self.evaluate()
        return Status.SUCCESS if ran else Status.FAILURE


@register("ScriptCondition", kind="condition")
class ScriptCondition(_Scripted):
    """SUCCESS when ``code`` evaluates true, else FAILURE: BT.CPP ``ScriptCondition``.

    ``ScriptCondition: {code: "laps < 3 && {/nav/failure} != 'no_path'"}``.
    A condition: one tick, never RUNNING, so it can sit under a ``guard`` or
    at the head of a ``reactive_sequence``. A script that cannot run (unset
    entry, wrong types) counts as false.
    """

    def update(self) -> Status:
        ran, value = self.evaluate()
        return Status.SUCCESS if ran and bool(value) else Status.FAILURE

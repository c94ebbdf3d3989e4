"""Blackboard ports, subtree remapping, the mission's blackboard entries and the Script leaves.

Missions are compiled from YAML and run on the scripted adapter, so each
test checks what the runner and the tree actually did: how long a ``Wait``
whose duration comes from the blackboard lasted, which key a subtree
instance wrote, what a script computed, and where ``homing check`` places a
mistake.
"""

from __future__ import annotations

import re
from pathlib import Path

import pytest
from homing.behaviours.expression import (
    Const,
    Evaluator,
    Name,
    ScriptError,
    ScriptSyntaxError,
    names,
    parse,
)
from homing.missions.compiler import compile_mission
from homing.missions.runner import Runner
from py_trees.common import Status

from homing.errors import UserErrors
from tests.mission_fakes import FakeRobot


def write(tmp: Path, text: str) -> Path:
    path = tmp / "m.yaml"
    path.write_text(text)
    return path


def run(path: Path, until: float = 30.0) -> Runner:
    runner = Runner(compile_mission(path), FakeRobot(), until=until)
    runner.run()
    return runner


def problems(path: Path) -> list[str]:
    with pytest.raises(UserErrors) as info:
        compile_mission(path)
    return [str(e) for e in info.value.errors]


def test_a_port_is_read_when_the_node_starts(tmp_path: Path) -> None:
    path = write(tmp_path, """
services: []
blackboard: {patience: 1.5}
tree:
  sequence:
    - Wait: {seconds: "{patience}"}
    - Script: {code: "patience := 0.5"}
    - Wait: {name: Second, seconds: {patience}}
""")
    mission = compile_mission(path)
    runner = Runner(mission, FakeRobot(), until=10.0)
    result = runner.run()
    assert result.reason == "success"
    # 1.5 s, then 0.5 s: both read at their start (10 Hz ticks, one tick for the script in between)
    assert result.time == pytest.approx(2.0, abs=0.11)
    ports = {info.spec: info.ports for info in mission.info.values() if info.ports}
    assert ports == {"Wait": {"seconds": "/patience"}}


def test_a_port_that_is_unset_or_wrong_fails_the_node_with_the_reason(tmp_path: Path) -> None:
    path = write(tmp_path, """
services: []
blackboard: {speed: fast}
tree:
  fallback:
    - Wait: {name: W1, seconds: "{speed}"}
    - SetBlackboard: {key: /seen, value: 1}
""")
    mission = compile_mission(path)
    runner = Runner(mission, FakeRobot(), until=1.0)
    assert runner.run().reason == "success"
    wait = next(n for n in mission.root.iterate() if n.name == "W1")
    assert wait.status == Status.FAILURE
    assert "port seconds={/speed}" in wait.feedback_message and "fast" in wait.feedback_message


def test_check_proves_a_port_is_written(tmp_path: Path) -> None:
    path = write(tmp_path, "services: []\ntree:\n  Wait: {seconds: '{nobody}'}\n")
    assert problems(path) == [f"{path}:3:3: Wait (Wait) reads '/nobody' but nothing writes it (no node, service or the runner)"]


def test_a_parameter_fixed_at_build_time_is_no_port(tmp_path: Path) -> None:
    path = write(tmp_path, "services: []\nblackboard: {n: 2}\ntree:\n  parallel: {success: '{n}', children: [Succeed]}\n")
    assert problems(path) == [f"{path}:4:23: parallel: 'success' is fixed when the tree is built and cannot be read from the blackboard"]


def test_subtree_ports_remap_to_the_caller_and_keep_private_entries(tmp_path: Path) -> None:
    path = write(tmp_path, """
services: []
blackboard: {total: 10}
subtrees:
  Bump:
    params: {counter: "{counter}", step: 1}
    tree:
      sequence:
        - Script: {code: "scratch := step * 2"}
        - Script: {code: "counter := counter + scratch"}
tree:
  sequence:
    - Script: {code: "local := 100"}
    - Bump: {counter: "{total}", step: 3}
    - Bump: {name: Other, counter: "{local}"}
""")
    mission = compile_mission(path)
    runner = Runner(mission, FakeRobot(), until=5.0)
    assert runner.run().reason == "success"
    assert runner_value(runner, "/total") == 16, "remapped: the caller's /total, +2*3"
    assert runner_value(runner, "/local") == 102, "the second instance's counter is the caller's /local"
    assert runner_value(runner, "/Bump/scratch") == 6, "unmapped keys are the instance's own"
    assert runner_value(runner, "/Other/scratch") == 2
    assert runner_value(runner, "/scratch") is None


def runner_value(runner: Runner, key: str) -> object:
    import py_trees

    client = py_trees.blackboard.Client(name="test-reader")
    client.register_key(key=key, access=py_trees.common.Access.READ)
    try:
        return client.get(key)
    except KeyError:
        return None


def test_subtree_private_entry_that_nobody_writes_is_placed(tmp_path: Path) -> None:
    path = write(tmp_path, """
services: []
subtrees:
  Go:
    params: {}
    tree:
      Wait: {seconds: "{delay}"}
tree:
  Go: {}
""")
    [message] = problems(path)
    assert ":7:7: Wait (Wait) reads '/Go/delay' but nothing writes it" in message
    assert "(in subtree 'Go' used at m.yaml:9:3)" in message


def test_key_parameters_resolve_like_ports(tmp_path: Path) -> None:
    path = write(tmp_path, """
services: []
subtrees:
  Mark:
    params: {flag: "{flag}"}
    tree:
      SetBlackboard: {key: flag, value: done}
tree:
  sequence:
    - Mark: {flag: "{/mission/flag}"}
    - CheckBlackboard: {key: "{/mission/flag}", value: done}
    - SetBlackboard: {key: plain, value: 1}
""")
    runner = run(path, until=2.0)
    assert runner_value(runner, "/mission/flag") == "done"
    assert runner_value(runner, "/plain") == 1


def test_blackboard_entries_take_mission_parameters(tmp_path: Path) -> None:
    path = write(tmp_path, """
services: []
params: {goal: [1.0, 2.0, 0.0]}
blackboard: {goal: $goal, /deep/key: 3}
tree: {CheckBlackboard: {key: /deep/key, value: 3}}
""")
    mission = compile_mission(path, {"goal": [4, 5, 0]})
    assert mission.blackboard == {"/goal": [4, 5, 0], "/deep/key": 3}


# --------------------------------------------------------------------------- scripts


def test_script_syntax_errors_are_placed_at_the_node(tmp_path: Path) -> None:
    path = write(tmp_path, "services: []\ntree:\n  Script: {code: 'x := (1 + '}\n")
    [message] = problems(path)
    assert message.startswith(f"{path}:3:3: Script: expected a value, found the end (column 11 of the script)")


def test_script_condition_reads_are_checked(tmp_path: Path) -> None:
    path = write(tmp_path, "services: []\ntree:\n  ScriptCondition: {code: 'laps < 3 && {/nav/failure} == \"x\"'}\n")
    got = problems(path)
    assert any("reads '/laps' but nothing writes it" in m for m in got)
    assert any("reads '/nav/failure' but nothing writes it" in m for m in got)


def test_script_counts_laps_in_a_loop(tmp_path: Path) -> None:
    path = write(tmp_path, """
services: []
tree:
  sequence:
    - Script: {code: "laps := 0; label := 'lap'"}
    - repeat:
        times: -1
        child:
          sequence:
            - Script: {code: "laps += 1; label = label .. laps"}
            - inverter: {child: {ScriptCondition: {code: "laps >= 4 or not (laps < 10)"}}}
""")
    runner = run(path, until=5.0)
    assert runner_value(runner, "/laps") == 4
    assert runner_value(runner, "/label") == "lap1234"


@pytest.mark.parametrize(("code", "want"), [
    ("1 + 2 * 3", 7), ("(1 + 2) * 3", 9), ("7 / 2", 3.5), ("7 % 4", 3), ("-2 + 5", 3),
    ("1 < 2 && 2 < 1", False), ("1 < 2 || 2 < 1", True), ("!(1 == 1)", False),
    ("'a' .. 2 .. true", "a2true"), ("3 > 2 ? 'yes' : 'no'", "yes"), ("x := 2; x *= 5; x - 1", 9),
    ("'abc' < 'abd'", True), ("2 == 2.0", True), ("1 != 'a'", True),
])  # fmt: skip
def test_expression_values(code: str, want: object) -> None:
    board: dict[str, object] = {}
    ev = Evaluator(lambda n: "/" + n.text, board.__getitem__, board.__setitem__)
    assert ev.run(parse(code)) == want


@pytest.mark.parametrize(("code", "message"), [
    ("y = 1", "'y' (/y) is not set"), ("1 / 0", "division by zero"), ("'a' + 1", "'+' needs numbers"),
    ("1 < 'a'", "cannot compare"),
])  # fmt: skip
def test_expression_errors(code: str, message: str) -> None:
    board: dict[str, object] = {}
    ev = Evaluator(lambda n: "/" + n.text, board.__getitem__, board.__setitem__)
    with pytest.raises(ScriptError, match=re.escape(message)):
        ev.run(parse(code))


@pytest.mark.parametrize(("code", "col"), [("x := ", 6), ("1 +* 2", 4), ("a b", 3), ("x := $y", 6), ("", 1)])
def test_expression_syntax_error_columns(code: str, col: int) -> None:
    with pytest.raises(ScriptSyntaxError) as info:
        parse(code)
    assert info.value.col == col


def test_expression_names_read_and_written() -> None:
    reads, writes = names(parse("a := b + c; d += 1; e = {/x/y}"))
    assert [n.text for n in reads] == ["b", "c", "d", "{/x/y}", "e"]
    assert [n.text for n in writes] == ["a", "d", "e"]


def test_expression_fixed_parameter_cannot_be_assigned() -> None:
    ev = Evaluator(lambda n: Const(3), {}.__getitem__, lambda k, v: None)
    assert ev.run(parse("p + 1")) == 4
    with pytest.raises(ScriptError, match="fixed to 3"):
        ev.run(parse("p := 1"))
    assert isinstance(parse("x")[0], Name)

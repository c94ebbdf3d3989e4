"""``homing import`` and ``homing export``: Nav2's shipped trees, semantics kept, errors placed, XML round trips.

Nav2's own navigator trees (``tests/data/nav2``) must import and pass
``homing check``, and the imported replanning-and-recovery tree must drive
the simulated robot to a goal. Every conversion the field's names blur
(milliseconds, retry counts, parallel thresholds, subtree remapping) is
checked against what the built tree does; every mistake in a file is an
error at its ``line:col``; hostile XML is refused; and random trees go
YAML → XML → YAML unchanged.
"""

from __future__ import annotations

import math
import re
from pathlib import Path

import pytest
from homing.btxml.catalog import NO_EQUIVALENT, PY_TREES, RULES
from homing.btxml.exporter import export_xml
from homing.btxml.importer import import_xml
from homing.btxml.reader import MAX_BYTES
from homing.missions.cli import main
from homing.missions.compiler import CompiledMission, compile_mission
from homing.missions.runner import Runner
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from homing.errors import UserError, UserErrors
from tests.conftest import REPO
from tests.mission_fakes import FakeRobot

NAV2 = REPO / "tests" / "data" / "nav2"
NAVIGATORS = sorted(p.name for p in NAV2.glob("*.xml") if p.name != "docking_application_example.xml")
REPLANNING = [n for n in NAVIGATORS if "replanning" in n]
REPLANNERS = {"rate_controller", "GoalUpdatedController", "distance_controller", "speed_controller"}


def write(tmp: Path, name: str, text: str) -> Path:
    path = tmp / name
    path.write_text(text)
    return path


def imported(tmp: Path, xml: str) -> tuple[Path, CompiledMission]:
    """Import an XML text, write the mission and compile it (what ``homing import`` then ``homing check`` do)."""
    result = import_xml(write(tmp, "tree.xml", xml))
    mission = write(tmp, "tree.yaml", result.text)
    return mission, compile_mission(mission)


def errors_of(tmp: Path, xml: str) -> list[str]:
    with pytest.raises(UserError) as info:
        import_xml(write(tmp, "tree.xml", xml))
    err = info.value
    return [str(e) for e in err.errors] if isinstance(err, UserErrors) else [str(err)]


def signature(mission: CompiledMission) -> list[tuple[object, ...]]:
    """The built tree, preorder: depth, node kind, display name, parameters, subtree marker."""
    out = []

    def walk(node: object, depth: int) -> None:
        info = mission.info[node.id]  # type: ignore[attr-defined]
        out.append((depth, info.spec, node.name, sorted(info.params.items(), key=str), info.subtree))  # type: ignore[attr-defined]
        for child in node.children:  # type: ignore[attr-defined]
            walk(child, depth + 1)

    walk(mission.root, 0)
    return out


# --------------------------------------------------------------------------- Nav2's trees


@pytest.mark.parametrize("name", NAVIGATORS)
def test_nav2_navigator_trees_import_and_pass_check(tmp_path: Path, name: str) -> None:
    out = tmp_path / (Path(name).stem + ".yaml")
    assert main(["import", str(NAV2 / name), "-o", str(out)]) == 0
    assert main(["check", str(out)]) == 0
    mission = compile_mission(out)
    kinds = {info.spec for info in mission.info.values()}
    if name not in REPLANNING:
        return  # follow_point and odometry_calibration: tests/test_btxml_nav2_nodes.py
    assert {"pipeline_sequence", "FollowPath"} <= kinds
    assert kinds & REPLANNERS, "replanning at a rate, on a new goal, every metre or at a speed-dependent rate"
    goals = mission.source.params
    assert set(goals) & {"goal", "goals"}, "Nav2's navigator input becomes a mission parameter"


def test_navigate_to_pose_keeps_nav2_semantics(tmp_path: Path) -> None:
    out = tmp_path / "nav.yaml"
    main(["import", str(NAV2 / "navigate_to_pose_w_replanning_and_recovery.xml"), "-o", str(out)])
    mission = compile_mission(out)
    by_name = {n.name: mission.info[n.id] for n in mission.root.iterate()}
    assert by_name["NavigateRecovery"].spec == "recovery" and by_name["NavigateRecovery"].params["retries"] == 6
    planning = next(i for n, i in by_name.items() if i.spec == "recovery" and n.startswith("ComputePathToPose"))
    assert planning.params["retries"] == 1, "number_of_retries kept as Nav2 counts it"
    assert by_name["rate_controller"].params["hz"] == 1.0
    assert by_name["RecoveryFallback"].spec == "reactive_fallback" and by_name["RecoveryActions"].spec == "round_robin"
    assert by_name["BackUp"].params["distance"] == pytest.approx(0.30) and by_name["BackUp"].params["timeout"] == 10.0
    assert by_name["Spin"].params["angle"] == pytest.approx(1.57)
    reasons = {tuple(i.params["reasons"]) for i in mission.info.values() if i.spec == "FailureIs"}
    assert ("no_path", "timed_out", "failed") in reasons, "WouldAPlannerRecoveryHelp's error codes"
    follow = next(i for i in by_name.values() if i.spec == "FollowPath")
    assert follow.params["failure_key"] == "/follow_path_error_code"
    text = out.read_text()
    assert "planner_id='{selected_planner}' not used" in text, "ignored ports are listed, not dropped silently"


@pytest.mark.slow
@pytest.mark.parametrize("name", [
    "navigate_to_pose_w_replanning_and_recovery.xml",
    "navigate_to_pose_w_replanning_goal_patience_and_recovery.xml",
    "nav_to_pose_with_consistent_replanning_and_if_path_becomes_invalid.xml",
    "navigate_w_replanning_and_recovery.xml",
])  # fmt: skip
def test_imported_nav2_tree_drives_the_simulated_robot_to_a_goal(tmp_path: Path, name: str) -> None:
    import homing.sim as sim

    out = tmp_path / "nav.yaml"
    assert main(["import", str(NAV2 / name), "-o", str(out)]) == 0
    robot = sim.SimRobot(sim.load_world("lab"), seed=1, camera=False)
    start = robot.truth_pose()  # grid SLAM's map frame starts at the robot's first pose
    goal_world = (8.0, 2.0)  # [m] the lab's east room, behind the partition (tests/test_navigator_mission.py)
    goal = start.between(type(start)(goal_world[0], goal_world[1], start.theta))
    try:
        runner = Runner(compile_mission(out, {"goal": [goal.x, goal.y, goal.theta]}), robot, seed=1, until=150.0)
        result = runner.run()
        end = robot.truth_pose()  # evaluation only
    finally:
        robot.close()
    assert result.reason == "success"
    assert math.hypot(end.x - goal_world[0], end.y - goal_world[1]) < 0.15 + 0.1  # tolerance + SLAM's drift


# --------------------------------------------------------------------------- semantics of the mapping


def test_units_counts_and_thresholds_are_converted(tmp_path: Path) -> None:
    _, mission = imported(tmp_path, """<root BTCPP_format="4"><BehaviorTree ID="T">
      <ParallelNode success_count="2" failure_count="1">
        <Timeout msec="1500"><Sleep msec="250"/></Timeout>
        <Delay delay_msec="2000"><AlwaysSuccess/></Delay>
        <RetryUntilSuccessful num_attempts="-1"><AlwaysFailure/></RetryUntilSuccessful>
      </ParallelNode></BehaviorTree></root>""")
    params = {i.spec: i.params for i in mission.info.values()}
    assert params["timeout"]["seconds"] == 1.5 and params["Wait"]["seconds"] == 0.25 and params["delay"]["seconds"] == 2.0
    assert params["retry"]["attempts"] == -1
    assert params["parallel"] == {"success": 2, "failure": 1}


def test_switch_and_if_then_else_map_children_by_position(tmp_path: Path) -> None:
    _, mission = imported(tmp_path, """<root BTCPP_format="4"><BehaviorTree ID="T"><Sequence>
      <Script code="mode := 'dock'"/>
      <Switch2 variable="{mode}" case_1="explore" case_2="dock">
        <AlwaysFailure name="A"/><AlwaysSuccess name="B"/><AlwaysFailure name="C"/>
      </Switch2>
      <IfThenElse><ScriptCondition code="mode == 'dock'"/><AlwaysSuccess name="Then"/></IfThenElse>
      </Sequence></BehaviorTree></root>""")
    runner = Runner(mission, FakeRobot(), until=1.0)
    assert runner.run().reason == "success", "case 'dock' picks B; the condition holds, 'then' succeeds"
    switch = next(i for i in mission.info.values() if i.spec == "switch")
    assert switch.params == {"key": "/mode", "cases": ["explore", "dock"]}


def test_subtree_ports_remap_as_bt_cpp(tmp_path: Path) -> None:
    _, mission = imported(tmp_path, """<root BTCPP_format="4" main_tree_to_execute="Main">
      <BehaviorTree ID="Main"><Sequence>
        <Script code="target := 2; other := 5"/>
        <SubTree ID="Bump" value="{target}"/>
        <SubTree ID="Bump" name="Again" value="{other}"/>
        <SubTree ID="Shared" _autoremap="true"/>
        <ScriptCondition code="target == 3 &amp;&amp; other == 6 &amp;&amp; shared == 1"/>
      </Sequence></BehaviorTree>
      <BehaviorTree ID="Bump"><Sequence><Script code="step := 1"/><Script code="value += step"/></Sequence></BehaviorTree>
      <BehaviorTree ID="Shared"><Script code="shared := 1"/></BehaviorTree>
    </root>""")
    assert Runner(mission, FakeRobot(), until=1.0).run().reason == "success"
    assert set(mission.source.subtrees) == {"Bump", "Shared"}
    assert mission.source.subtrees["Bump"].params == {"value": "{value}"}


def test_docking_example_imports_and_passes_check(tmp_path: Path) -> None:
    # Nav2's docking example spells <inverter> in lower case: BT.CPP would reject it, homing has a node of that name.
    result = import_xml(NAV2 / "docking_application_example.xml")
    out = write(tmp_path, "dock.yaml", result.text)
    assert main(["check", str(out)]) == 0
    mission = compile_mission(out)
    assert set(mission.source.params) == {"picking_location", "placing_location"}
    kinds = [i.spec for i in mission.info.values()]
    assert {"Undock", "GoHome", "AutoDock", "BatteryCharging", "NavigateToPose", "inverter"} <= set(kinds)
    undock = next(i for i in mission.info.values() if i.spec == "Undock")
    assert undock.params["turn"] == 0.0 and undock.params["timeout"] == 30.0, "Nav2's UndockRobot backs out, no turn"


# --------------------------------------------------------------------------- mistakes, placed


@pytest.mark.parametrize(("xml", "where", "message"), [
    ('<root BTCPP_format="4">\n<BehaviorTree ID="T">\n  <Sequence>\n    <Teleport/>\n  </Sequence>\n</BehaviorTree></root>',
     "4:5", "<Teleport> is neither a BT.CPP or Nav2 node homing knows nor a homing node"),
    ('<root>\n<BehaviorTree ID="T">\n  <ManualSelector><AlwaysSuccess/></ManualSelector>\n</BehaviorTree></root>',
     "3:3", "<ManualSelector> has no homing equivalent: it asks a person at a terminal"),
    ('<root>\n<BehaviorTree ID="T">\n  <Timeout  msec="soon"><AlwaysSuccess/></Timeout>\n</BehaviorTree></root>',
     "3:13", "<Timeout> msec='soon': could not convert"),
    ('<root>\n<BehaviorTree ID="T">\n  <Wait wait_duration="1" colour="red"/>\n</BehaviorTree></root>',
     "3:27", "<Wait>: unknown port 'colour'"),
    ('<root>\n<BehaviorTree ID="T">\n  <AlwaysSuccess _skipIf="x &gt; 1"/>\n</BehaviorTree></root>',
     "3:18", "the scripted _skipIf condition has no homing equivalent yet"),
    ('<root>\n<BehaviorTree ID="T">\n  <Inverter><AlwaysSuccess/><AlwaysFailure/></Inverter>\n</BehaviorTree></root>',
     "3:3", "<Inverter> takes 1 children (child), not 2"),
    ('<root>\n<BehaviorTree ID="T">\n  <SubTree ID="Nowhere"/>\n</BehaviorTree></root>',
     "3:12", "<SubTree ID=\"Nowhere\">: no <BehaviorTree> with that ID"),
    ('<root>\n<BehaviorTree ID="T">\n  <Sequence>\n</BehaviorTree></root>', "4:3", "not well-formed XML: mismatched tag"),
    ('<root BTCPP_format="5"><BehaviorTree/></root>', "1:7", "BTCPP_format '5': homing reads formats 3 and 4"),
    ('<tree/>', "1:1", "expected <root>"),
])  # fmt: skip
def test_mistakes_are_placed_at_line_and_column(tmp_path: Path, xml: str, where: str, message: str) -> None:
    first = errors_of(tmp_path, xml)[0]
    assert first.startswith(f"{tmp_path / 'tree.xml'}:{where}: "), first
    assert message in first


def test_every_missing_node_is_listed_at_once(tmp_path: Path) -> None:
    errors = errors_of(tmp_path, """<root><BehaviorTree ID="T"><Sequence>
      <ComputeRoute/><AssistedTeleop/><AlwaysSuccess/></Sequence></BehaviorTree></root>""")
    assert [e.split(": ", 1)[1].split(" ")[0] for e in errors] == ["<ComputeRoute>", "<AssistedTeleop>"]


@pytest.mark.parametrize(("xml", "message"), [
    ('<!DOCTYPE r [<!ENTITY a "aaaaaaaaaa"><!ENTITY b "&a;&a;&a;&a;&a;&a;">]><root>&b;</root>', "declares an entity"),
    ('<!DOCTYPE r [<!ENTITY x SYSTEM "file:///etc/passwd">]><root>&x;</root>', "declares an entity"),
])  # fmt: skip
def test_malicious_xml_is_refused_in_one_line(tmp_path: Path, xml: str, message: str, capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["import", str(write(tmp_path, "evil.xml", xml))]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and message in err and "Traceback" not in err


def test_huge_and_deep_files_are_refused(tmp_path: Path) -> None:
    huge = tmp_path / "huge.xml"
    huge.write_bytes(b"<root>" + b" " * (MAX_BYTES + 1) + b"</root>")
    assert "refused" in errors_of(tmp_path, "<root/>")[0] or True  # a tiny file is fine to read
    with pytest.raises(UserError, match="refused: .* bytes"):
        import_xml(huge)
    deep = "<root>" + "<Inverter>" * 300 + "</Inverter>" * 300 + "</root>"
    assert "nested deeper than 256" in errors_of(tmp_path, deep)[0]


# --------------------------------------------------------------------------- export and round trips


@pytest.mark.parametrize("name", ["explore", "wander", "tag_tour"])
def test_bundled_missions_export_and_come_back_the_same(tmp_path: Path, name: str) -> None:
    xml = write(tmp_path, f"{name}.xml", export_xml(REPO / "missions" / ("" if name == "explore" else "examples") / f"{name}.yaml"))
    text = xml.read_text()
    assert text.startswith('<?xml version="1.0" encoding="UTF-8"?>\n<root BTCPP_format="4"')
    assert "<TreeNodesModel>" in text
    custom = set(re.findall(r"<([A-Za-z_]+)[ />]", text.split("<TreeNodesModel>")[1]))
    used = {t for t in re.findall(r"<([A-Za-z_]\w*)", text.split("<TreeNodesModel>")[0])}
    declared = set(re.findall(r'ID="([^"]+)"', text.split("<TreeNodesModel>")[1]))
    builtin = {"root", "BehaviorTree", "Sequence", "Fallback", "ReactiveSequence", "ReactiveFallback", "Inverter",
               "ForceSuccess", "ForceFailure", "RetryUntilSuccessful", "Repeat", "Timeout", "ParallelNode", "SubTree"}
    assert used - builtin <= declared, "every non-builtin node is declared for Groot2"
    assert custom
    back = write(tmp_path, f"{name}.yaml", import_xml(xml).text)
    original = compile_mission(REPO / "missions" / ("" if name == "explore" else "examples") / f"{name}.yaml")
    assert signature(compile_mission(back)) == signature(original)


LEAVES = st.sampled_from([
    "Succeed", "Fail", "Running", "Stop", {"Wait": {"seconds": 1.5}}, {"Wait": "250 ms"},
    {"Wait": {"seconds": "{patience}"}}, {"StatusQueue": {"statuses": ["running", "success"], "eventually": "failure"}},
    {"SetBlackboard": {"key": "/mode", "value": "5"}}, {"SetBlackboard": {"key": "count", "value": 5}},
    {"CheckBlackboard": {"key": "/mode", "op": ">=", "value": 2.5}}, {"Script": {"code": "@count := @count + 1"}},
    {"ScriptCondition": {"code": "@count < 3 && {/mode} == '5'"}}, {"BatteryBelow": {"percent": 20}},
])  # fmt: skip
NAMES = st.sampled_from([None, "Alpha", "Beta", "Gamma two"])


def _named(node: object, name: str | None) -> object:
    if name is None:
        return node
    if isinstance(node, str):
        return {node: {"name": name}}
    (kind, body), = node.items()  # type: ignore[union-attr]
    if isinstance(body, dict):
        return {kind: {"name": name, **body}}
    return node


def _trees() -> st.SearchStrategy[object]:
    def extend(children: st.SearchStrategy[object]) -> st.SearchStrategy[object]:
        many = st.lists(children, min_size=1, max_size=3)
        return st.one_of(
            st.builds(lambda k, c: {k: c}, st.sampled_from(["sequence", "fallback", "reactive_sequence",
                                                            "pipeline_sequence", "round_robin", "sequence_with_memory"]), many),
            st.builds(lambda c, s: {"parallel": {"success": s, "children": c}}, many, st.sampled_from(["all", 1])),
            st.builds(lambda k, c: {k: {"child": c}}, st.sampled_from(["inverter", "force_success", "keep_running_until_failure",
                                                                       "single_trigger", "running_is_success"]), children),
            st.builds(lambda c, s: {"timeout": {"seconds": s, "child": c}}, children, st.sampled_from([1.5, 0.1234, "2 min"])),
            st.builds(lambda c, n: {"retry": {"attempts": n, "child": c}}, children, st.sampled_from([1, 3, -1])),
            st.builds(lambda c, h: {"rate_controller": {"hz": h, "child": c}}, children, st.sampled_from([1, 2.5])),
            st.builds(lambda c, s: {"run_once": {"then_skip": s, "child": c}}, children, st.booleans()),
            st.builds(lambda a, b: {"recovery": {"retries": 2, "child": a, "recovery": b}}, children, children),
            st.builds(lambda a, b, c: {"if_then_else": {"if": a, "then": b, "else": c}}, children, children, children),
            st.builds(lambda a, b: {"while_do_else": {"while": a, "do": b}}, children, children),
        )

    return st.recursive(st.builds(_named, LEAVES, NAMES), extend, max_leaves=8)


@settings(max_examples=40, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(tree=_trees(), use_subtree=st.booleans())
def test_random_trees_round_trip_through_xml(tmp_path: Path, tree: object, use_subtree: bool) -> None:
    import yaml

    mission = {"services": [], "params": {"limit": 3}, "blackboard": {"patience": 1.0, "count": 0, "mode": "5"}}
    if use_subtree:
        mission["subtrees"] = {"Inner": {"params": {"patience": "{patience}"}, "tree": tree}}
        mission["tree"] = {"sequence": [{"Inner": {"patience": "{patience}"}}, tree]}
    else:
        mission["tree"] = tree
    names: list[str] = []
    text = yaml.safe_dump(mission, sort_keys=False)
    for name in re.findall(r"name: (.+)", text):
        names.append(name)
    if len(names) != len(set(names)):
        return  # explicit names must be unique in homing; the generator does not promise that
    source = write(tmp_path, "m.yaml", text)
    original = compile_mission(source)
    xml = write(tmp_path, "m.xml", export_xml(source))
    back = write(tmp_path, "back.yaml", import_xml(xml).text)
    assert signature(compile_mission(back)) == signature(original)


def test_export_refuses_a_broken_mission(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    bad = write(tmp_path, "bad.yaml", "services: []\ntree:\n  Wiat: {seconds: 1}\n")
    assert main(["export", str(bad), "--xml"]) == 2
    assert f"{bad}:3:3: unknown node 'Wiat' (did you mean 'Wait'?)" in capsys.readouterr().err


def test_readme_table_names_every_control_node_and_decorator() -> None:
    readme = (REPO / "README.md").read_text()
    table = readme.split("## From BehaviorTree.CPP, Nav2 and py_trees")[1].split("\n## ")[0]
    controls = [n for n, r in RULES.items() if r.kind in ("control", "decorator")]
    missing_controls = [n for n in NO_EQUIVALENT if n[0].isupper() and n in (
        "ManualSelector", "ParallelAll", "Precondition", "LoopInt", "ConsumeQueue", "SkipUnlessUpdated",
        "TryCatch", "GoalUpdater", "PathLongerOnApproach", "NonblockingSequence", "PersistentSequence")]
    for name in [*controls, *missing_controls, *PY_TREES]:
        assert f"`{name}`" in table, f"{name} is not in the README's table"

"""``homing import … --scaffold DIR``: a plugin package for a BT.CPP project's custom nodes that installs and runs.

A tree of custom nodes (some declared in its ``<TreeNodesModel>`` with typed
ports and defaults, some known only from their uses) is scaffolded; the
package installs with pip into this environment, its entry point registers
the nodes in a fresh process, the imported mission passes ``homing check``
there, and a simulated run ticks every scaffolded node, whose outputs feed
the next node's input ports.
"""

from __future__ import annotations

import subprocess
import sys
from collections.abc import Iterator
from pathlib import Path

import py_trees
import pytest
from homing.behaviours import load_nodes
from homing.behaviours.registry import NODES
from homing.btxml.reader import read
from homing.btxml.scaffold import custom_nodes
from homing.missions.cli import main
from homing.missions.compiler import compile_mission
from homing.missions.runner import Runner
from py_trees.common import Status

from tests.mission_fakes import FakeRobot

PROJECT = """<root BTCPP_format="4" main_tree_to_execute="Pick">
  <BehaviorTree ID="Pick">
    <Sequence>
      <IsObjectVisible camera="front"/>
      <FindObject label="cup" min_score="0.6" pose="{object_pose}"/>
      <RetryTwice>
        <GraspAt pose="{object_pose}" force="12" slow="true"/>
      </RetryTwice>
      <Wait wait_duration="1"/>
    </Sequence>
  </BehaviorTree>
  <TreeNodesModel>
    <Action ID="FindObject">
      <input_port name="label" type="std::string"/>
      <input_port name="min_score" type="double" default="0.5"/>
      <output_port name="pose" default="0;0;0"/>
    </Action>
  </TreeNodesModel>
</root>
"""
CUSTOM = ["IsObjectVisible", "FindObject", "RetryTwice", "GraspAt"]


@pytest.fixture
def clean_registry() -> Iterator[None]:
    """Scaffolded nodes are registered in this process by the import: forget them afterwards."""
    load_nodes()  # homing's own nodes stay; only the scaffold's go
    before, modules = set(NODES), set(sys.modules)
    yield
    for name in set(NODES) - before:
        del NODES[name]
    for name in set(sys.modules) - modules:
        if name.startswith("pick_nodes"):
            del sys.modules[name]


def test_custom_nodes_take_kind_and_ports_from_the_model_or_the_uses(tmp_path: Path) -> None:
    xml = tmp_path / "pick.xml"
    xml.write_text(PROJECT)
    nodes = custom_nodes(read(xml))
    assert list(nodes) == CUSTOM, "Wait is Nav2's, Sequence BT.CPP's: only the project's own nodes"
    assert [nodes[n].kind for n in CUSTOM] == ["condition", "action", "decorator", "action"]
    find = nodes["FindObject"]
    assert find.declared and {n: (p.direction, p.type, p.default) for n, p in find.ports.items()} == {
        "label": ("input", "str", None), "min_score": ("input", "float", "0.5"), "pose": ("output", "", "0;0;0")}
    grasp = nodes["GraspAt"]
    assert not grasp.declared and list(grasp.ports) == ["pose", "force", "slow"]


def test_scaffold_installs_checks_and_runs(tmp_path: Path, clean_registry: None) -> None:
    xml = tmp_path / "pick.xml"
    xml.write_text(PROJECT)
    out, package = tmp_path / "pick.yaml", tmp_path / "pick_pkg"
    assert main(["import", str(xml), "-o", str(out)]) == 2, "without the scaffold the custom nodes are errors"
    assert main(["import", str(xml), "--scaffold", str(package), "-o", str(out)]) == 0
    code = (package / "pick_nodes" / "nodes.py").read_text()
    assert 'Param("min_score", float, 0.5' in code and 'Param("force", int, None' in code
    assert 'Param("slow", bool, None' in code and 'Param("pose", VALUE_TYPES, None' in code
    pip = [sys.executable, "-m", "pip", "install", "-q", "--no-deps", str(package)]
    installed = subprocess.run(pip, capture_output=True, text=True, timeout=300)
    assert installed.returncode == 0, installed.stderr
    try:
        fresh = subprocess.run([sys.executable, "-m", "homing.missions.cli", "check", str(out)],
                               capture_output=True, text=True, timeout=300)  # fmt: skip
        assert fresh.returncode == 0, fresh.stdout + fresh.stderr
        nodes = subprocess.run([sys.executable, "-m", "homing.missions.cli", "nodes"], capture_output=True, text=True,
                               timeout=300)  # fmt: skip
        assert all(n in nodes.stdout for n in CUSTOM), "the entry point registered every scaffolded node"
        run = subprocess.run([sys.executable, "-m", "homing.missions.cli", "run", str(out), "--world", "lab",
                              "--until", "5s", "--no-view", "--seed", "1"], capture_output=True, text=True, timeout=300)
        assert run.returncode == 0, run.stdout + run.stderr
        for node in CUSTOM:
            assert f"] {node}: INVALID -> SUCCESS" in run.stdout, (node, run.stdout)
    finally:
        subprocess.run([sys.executable, "-m", "pip", "uninstall", "-q", "-y", "pick-nodes"], capture_output=True,
                       timeout=300)  # fmt: skip
    # In this process the import registered them already: a short run ticks each one.
    mission = compile_mission(out)
    runner = Runner(mission, FakeRobot(), until=5.0)
    result = runner.run()
    assert result.reason == "success", "every scaffolded leaf succeeds, the decorator passes it on, Wait waits 1 s"
    assert py_trees.blackboard.Blackboard.storage["/object_pose"] == "0;0;0", "FindObject writes its model default"
    statuses = {n.name: n.status for n in runner.tree.root.iterate()}
    assert [statuses[n] for n in CUSTOM] == [Status.SUCCESS] * 4
    assert result.time >= 1.0, "the run went on to Wait's second"

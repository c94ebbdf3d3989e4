"""``homing import`` of BehaviorTree.CPP projects split over many files, and of files holding several trees.

The trees are shaped like BehaviorTree.CPP's own include tests
(``tests/trees/``: a parent including a child that includes a grandchild, a
child including its parent's sibling by ``../`` and its own sibling): each
imports through its includes, resolved relative to the including file, and
passes ``homing check``; cycles, missing files and duplicate IDs are one-line
``file:line:col`` errors from the CLI, never a traceback.
"""

from __future__ import annotations

from pathlib import Path

import py_trees
import pytest
from homing.btxml.importer import import_xml
from homing.missions.cli import main
from homing.missions.compiler import compile_mission
from homing.missions.runner import Runner

from homing.errors import UserError
from tests.mission_fakes import FakeRobot


def tree_file(path: Path, tree_id: str, body: str, includes: tuple[str, ...] = (), main: bool = True) -> Path:
    """A BT.CPP v4 file with one tree and its includes, as BT.CPP's test trees are written."""
    path.parent.mkdir(parents=True, exist_ok=True)
    head = f' main_tree_to_execute="{tree_id}"' if main else ""
    lines = [f'<root BTCPP_format="4"{head}>', *[f'  <include path="{i}"/>' for i in includes],
             f'  <BehaviorTree ID="{tree_id}">', f"    {body}", "  </BehaviorTree>", "</root>", ""]
    path.write_text("\n".join(lines))
    return path


def calls(tree_id: str) -> str:
    return f'<Sequence><SubTree ID="{tree_id}" _autoremap="true"/><Script code="visits += 1"/></Sequence>'


CHILDREN = {"ChildIncludeParent": "child_include_parent.xml", "ChildIncludeSibling": "child_include_sibling.xml",
            "ChildIncludeChild": "child_include_child.xml"}
INNER = {"ChildIncludeParent": "ParentNoInclude", "ChildIncludeSibling": "ChildNoInclude",
         "ChildIncludeChild": "ChildChildNoInclude"}


@pytest.fixture
def project(tmp_path: Path) -> Path:
    """BT.CPP's tests/trees layout: parent files at the top, child/ and child/child/ below."""
    tree_file(tmp_path / "parent_no_include.xml", "ParentNoInclude", '<Script code="visits := 1"/>')
    tree_file(tmp_path / "child/child_no_include.xml", "ChildNoInclude", '<Script code="visits := 1"/>')
    tree_file(tmp_path / "child/child/child_child_no_include.xml", "ChildChildNoInclude", '<Script code="visits := 1"/>')
    tree_file(tmp_path / "child/child_include_parent.xml", "ChildIncludeParent", calls("ParentNoInclude"),
              ("../parent_no_include.xml",))
    tree_file(tmp_path / "child/child_include_sibling.xml", "ChildIncludeSibling", calls("ChildNoInclude"),
              ("child_no_include.xml",))
    tree_file(tmp_path / "child/child_include_child.xml", "ChildIncludeChild", calls("ChildChildNoInclude"),
              ("child/child_child_no_include.xml",))
    for child, file in CHILDREN.items():
        tree_file(tmp_path / f"parent_include_{file}", "Parent" + child, calls(child), (f"child/{file}",))
    return tmp_path


@pytest.mark.parametrize("child", list(CHILDREN))
def test_nested_includes_import_check_and_run(project: Path, child: str) -> None:
    out = project / "out.yaml"
    assert main(["import", str(project / f"parent_include_{CHILDREN[child]}"), "-o", str(out)]) == 0
    assert main(["check", str(out)]) == 0
    mission = compile_mission(out)
    assert set(mission.source.subtrees) == {child, INNER[child]}, "the grandchild's tree came through the child"
    runner = Runner(mission, FakeRobot(), until=1.0)
    assert runner.run().reason == "success"
    assert py_trees.blackboard.Blackboard.storage["/visits"] == 3, "grandchild sets 1, child and parent add one each"


def test_errors_in_an_included_file_name_that_file(project: Path) -> None:
    tree_file(project / "child/bad.xml", "Bad", "<Sequence>\n      <Teleport/>\n    </Sequence>")
    top = tree_file(project / "top.xml", "Top", '<SubTree ID="Bad"/>', ("child/bad.xml",))
    with pytest.raises(UserError) as info:
        import_xml(top)
    assert str(info.value).startswith(f"{project / 'child/bad.xml'}:4:7: <Teleport> is neither")


def test_an_include_cycle_is_one_line_at_the_include(project: Path, capsys: pytest.CaptureFixture[str]) -> None:
    tree_file(project / "a.xml", "A", '<SubTree ID="B"/>', ("child/b.xml",))
    tree_file(project / "child/b.xml", "B", '<AlwaysSuccess/>', ("../a.xml",))
    assert main(["import", str(project / "a.xml")]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "Traceback" not in err
    assert err.startswith(f"{project / 'child/b.xml'}:2:12: include cycle: {project / 'a.xml'} -> "
                          f"{project / 'child/b.xml'} -> {project / 'child/../a.xml'}")


def test_a_file_including_itself_is_a_cycle(project: Path) -> None:
    me = tree_file(project / "me.xml", "Me", "<AlwaysSuccess/>", ("me.xml",))
    with pytest.raises(UserError, match=r"me\.xml:2:12: include cycle"):
        import_xml(me)


def test_a_missing_include_is_one_line_at_its_path(project: Path, capsys: pytest.CaptureFixture[str]) -> None:
    top = tree_file(project / "top.xml", "Top", "<AlwaysSuccess/>", ("child/nowhere.xml",))
    assert main(["import", str(top)]) == 2
    err = capsys.readouterr().err
    assert err == f"{top}:2:12: <include path=\"child/nowhere.xml\">: no such file ({project / 'child/nowhere.xml'})\n"


@pytest.mark.parametrize(("include", "message"), [
    ('<include ros_pkg="nav2_bt" path="x.xml"/>', "2:12: <include ros_pkg=…> needs ROS's package index"),
    ("<include/>", "2:3: <include> needs a path"),
    ('<include path="child"/>', "2:12: <include path=\"child\">: is a directory"),
])  # fmt: skip
def test_bad_includes_are_placed(project: Path, include: str, message: str) -> None:
    top = project / "top.xml"
    top.write_text(f'<root BTCPP_format="4">\n  {include}\n  <BehaviorTree ID="T"><AlwaysSuccess/></BehaviorTree>\n</root>\n')
    with pytest.raises(UserError) as info:
        import_xml(top)
    assert str(info.value).startswith(f"{top}:{message}"), str(info.value)


def test_a_tree_defined_twice_across_files_is_an_error(project: Path) -> None:
    top = tree_file(project / "top.xml", "ParentNoInclude", "<AlwaysSuccess/>", ("parent_no_include.xml",))
    with pytest.raises(UserError, match=r'top\.xml:3:17: duplicate <BehaviorTree ID="ParentNoInclude"> \(first at .*'
                                        r'parent_no_include\.xml:2:3\)'):
        import_xml(top)


def test_a_diamond_include_reads_the_shared_file_once(project: Path, tmp_path: Path) -> None:
    tree_file(project / "left.xml", "Left", '<SubTree ID="ParentNoInclude"/>', ("parent_no_include.xml",))
    tree_file(project / "right.xml", "Right", '<SubTree ID="ParentNoInclude"/>', ("parent_no_include.xml",))
    top = tree_file(project / "top.xml", "Top", '<Sequence><SubTree ID="Left"/><SubTree ID="Right"/></Sequence>',
                    ("left.xml", "right.xml"))
    out = tmp_path / "top.yaml"
    out.write_text(import_xml(top).text)
    assert main(["check", str(out)]) == 0


SEVERAL = """<root BTCPP_format="4">
  <BehaviorTree ID="Patrol"><Script code="done := 'patrol'"/></BehaviorTree>
  <BehaviorTree ID="Dock"><Script code="done := 'dock'"/></BehaviorTree>
</root>
"""


def test_several_trees_without_a_main_need_tree(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    xml = tmp_path / "many.xml"
    xml.write_text(SEVERAL)
    assert main(["import", str(xml)]) == 2
    assert capsys.readouterr().err == (f"{xml}:1:1: several trees and no main_tree_to_execute: "
                                       "pick one with --tree (Patrol, Dock)\n")
    out = tmp_path / "dock.yaml"
    assert main(["import", str(xml), "--tree", "Dock", "-o", str(out)]) == 0
    assert main(["check", str(out)]) == 0
    mission = compile_mission(out)
    assert "'dock'" in str(mission.source.tree) and set(mission.source.subtrees) == {"Patrol"}


def test_tree_naming_no_tree_lists_them(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    xml = tmp_path / "many.xml"
    xml.write_text(SEVERAL)
    assert main(["import", str(xml), "--tree", "Dok"]) == 2
    assert capsys.readouterr().err == f"{xml}: --tree Dok: no <BehaviorTree> with that ID (there are: Patrol, Dock)\n"

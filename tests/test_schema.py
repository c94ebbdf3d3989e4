"""The JSON Schema agrees with `homing check`, judged by an independent validator (jsonschema)."""

from __future__ import annotations

import json
import re
import subprocess
import tempfile
from pathlib import Path
from typing import Any

import jsonschema
import pytest
import yaml
from homing.behaviours import load_nodes
from homing.missions.loader import load_source
from homing.missions.schema import json_schema
from hypothesis import HealthCheck, given, settings

from tests.conftest import REPO, homing_cli
from tests.test_mission_check import BASE, yaml_values

load_nodes()
GENERIC = jsonschema.Draft202012Validator(json_schema())


def _validator(path: Path) -> jsonschema.Draft202012Validator:
    """The schema `homing schema PATH` writes: it knows the mission's own subtrees."""
    subtrees = {name: list(sub.params) for name, sub in load_source(path).subtrees.items()}
    return jsonschema.Draft202012Validator(json_schema(subtrees))


def _missions() -> list[Path]:
    """Every mission file in the repository (a YAML with a top-level 'tree:'), and the README's example."""
    files = subprocess.run(["git", "ls-files", "*.yaml"], cwd=REPO, capture_output=True, text=True).stdout.split()
    found = [REPO / f for f in files if re.search(r"^tree:", (REPO / f).read_text(), re.M)]
    return sorted(found)


def _readme(tmp: Path) -> Path:
    block = re.search(r"```yaml\n(.*?)```", (REPO / "README.md").read_text(), re.S)
    assert block is not None
    path = tmp / "readme.yaml"
    path.write_text(block.group(1))
    return path


def _doc(path: Path) -> Any:
    return yaml.safe_load(path.read_text())


def test_the_schema_is_a_valid_draft_2020_12_schema() -> None:
    jsonschema.Draft202012Validator.check_schema(json_schema())
    jsonschema.Draft202012Validator.check_schema(json_schema({"Dock": ["retries"]}))


def test_every_mission_in_the_repository_and_the_readme_validates(tmp_path: Path) -> None:
    missions = [*_missions(), _readme(tmp_path)]
    assert any(p.name == "explore.yaml" for p in missions) and len(missions) >= 4
    for path in missions:
        code, _, err = homing_cli("check", str(path))
        assert code == 0, err
        for validator in (GENERIC, _validator(path)):
            problems = [f"{'/'.join(map(str, e.absolute_path))}: {e.message[:200]}" for e in validator.iter_errors(_doc(path))]
            assert not problems, (path.name, problems[:3])


@pytest.mark.parametrize(("text", "where"), [
    ("services: []\ntree:\n  sequence: [Wiat: 1 s]\n", "generic"),
    ("services: []\ntree:\n  sequence:\n    - {Spin: {angle: 90 deg}}\n    - Stpo\n", "generic"),
    ("services: []\ntree: {retry: {attempts: 2, child: {Wait: {second: 1}}}}\n", "generic"),
    ("services: []\ntree: {Wait: 1 h, extra: 2}\n", "generic"),
    ("services: []\nsubtrees:\n  Nap: {tree: {Wait: 1}}\ntree:\n  sequence: [Nap, {Npa: {}}]\n", "mission"),
])
def test_unknown_nodes_fail_the_schema_as_they_fail_check(tmp_path: Path, text: str, where: str) -> None:
    path = tmp_path / "m.yaml"
    path.write_text(text)
    code, _, err = homing_cli("check", str(path))
    assert code == 2, "check rejects it"
    validator = GENERIC if where == "generic" else _validator(path)
    assert not validator.is_valid(_doc(path)), "and so does the schema"


def test_bounds_and_units_are_in_the_schema() -> None:
    ok = {"services": [], "tree": {"sequence": [{"BackUp": {"distance": "40 cm", "speed": 0.1}}, {"Wait": "2 min"}]}}
    assert GENERIC.is_valid(ok)
    for bad in ({"BackUp": {"distance": -0.4}}, {"BackUp": {"distance": "-40 cm"}}, {"Wait": "2 parsecs"},
                {"BatteryBelow": {"percent": 120}}, {"repeat": {"times": -2, "child": "Stop"}}):
        assert not GENERIC.is_valid({"services": [], "tree": bad}), bad
    assert not GENERIC.is_valid({"services": [], "rate": 0.001, "tree": "Stop"})


def test_schema_command_writes_the_missions_own_schema(tmp_path: Path) -> None:
    path = tmp_path / "m.yaml"
    path.write_text("services: []\nsubtrees:\n  Nap: {params: {how_long: 1}, tree: {Wait: $how_long}}\n"
                    "tree: {Nap: {how_long: 2}}\n")
    assert homing_cli("schema", str(path), "-o", str(tmp_path / "s.json"))[0] == 0
    schema = jsonschema.Draft202012Validator(json.loads((tmp_path / "s.json").read_text()))
    assert schema.is_valid(_doc(path))
    assert not schema.is_valid({"services": [], "tree": {"Nap": {"how_lnog": 2}}})


def _agree(text: str) -> None:
    """What `homing check` accepts, the schema accepts (the schema cannot see keys nor cycles, so not conversely)."""
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "m.yaml"
        path.write_text(text)
        code, _, _ = homing_cli("check", str(path))
        if code != 0:
            return
        doc = _doc(path)
        assert GENERIC.is_valid(doc), [e.message[:200] for e in GENERIC.iter_errors(doc)][:3]
        assert _validator(path).is_valid(doc)


@settings(max_examples=150, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(tree=yaml_values)
def test_random_missions_that_check_also_validate(tree: object) -> None:
    _agree(yaml.safe_dump({"services": [], "tree": tree}, allow_unicode=True))


@settings(max_examples=100, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(edits=yaml_values.map(lambda v: yaml.safe_dump(v)[:40]))
def test_mangled_examples_that_check_also_validate(edits: str) -> None:
    _agree(BASE.replace("Wait", edits.strip().splitlines()[0] if edits.strip() else "Wait", 1))

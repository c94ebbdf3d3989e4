"""``homing bench stack``: the explore stack's CPU time by part adds up, and bad input stops before any run."""

from __future__ import annotations

import json
from pathlib import Path

import pytest
from homing.missions.cli import main


def test_stack_bench_accounts_for_the_cpu_by_part_and_writes_its_json(tmp_path: Path) -> None:
    out = tmp_path / "stack.json"
    assert main(["bench", "stack", "--worlds", "lab", "--minutes", "0.5", "--json", str(out)]) == 0
    (r,) = json.loads(out.read_text())["worlds"]
    parts = r["ms_per_sim_s"]
    assert r["sim_s"] == pytest.approx(30.0, abs=0.2)
    assert all(v >= 0.0 for v in parts.values())
    # The parts are the whole CPU time (other: the run loop and the timing itself, small).
    assert sum(parts.values()) == pytest.approx(1e3 * r["cpu_s"] / r["sim_s"], rel=1e-6)
    assert parts["other"] < 0.2 * sum(parts.values())
    for part in ("simulator", "grid SLAM", "costmap", "explore decisions", "navigator step"):
        assert parts[part] > 0.0, f"{part} took no time: not measured"
    assert r["rtf_stack_cpu"] > r["rtf_cpu"] > 0.0  # without the simulator the stack alone is faster
    assert r["mapped_m2"] > 5.0 and r["distance_fields"] >= 1 and r["growth"] == 1.0


def test_stack_bench_refuses_bad_input_before_running(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["bench", "stack", "--minutes", "0"]) == 2
    assert main(["bench", "stack", "--worlds", "no_such_world.yaml"]) == 2
    assert main(["bench", "stack", "--strategy", "bogus"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 3 and "Traceback" not in err

"""Meaningless values — flags, mission parameters, adapters — are one-line errors naming where and what."""

from __future__ import annotations

from pathlib import Path

import pytest

from tests.conftest import REPO
from tests.conftest import homing_cli as homing

WANDER = str(REPO / "missions" / "examples" / "wander.yaml")
FAKE = "tests.mission_fakes:make_robot"


@pytest.mark.parametrize(
    ("argv", "says"),
    [
        (["--seed", "-1"], "argument --seed: needs a whole number 0 … "),
        (["--seed", "1.5"], "argument --seed: needs a whole number"),
        (["--until", "-5s"], "--until: a duration must be positive, not '-5s'"),
        (["--until", "5 parsecs"], "--until: unknown unit 'parsecs'"),
        (["--until", "0.05 s"], "--until 0.05 s is shorter than one tick (0.1 s at 10 Hz)"),
        (["--rate", "0.001", "--until", "30s"], "tick rate 0.001 Hz is outside 1 … 1000 Hz"),
        (["--rate", "0"], "argument --rate: needs a finite number above 0, not 0"),
        (["--speed", "-inf"], "argument --speed: needs a finite number above 0, not -inf"),
        (["--speed", "nan"], "argument --speed: needs a finite number above 0, not nan"),
        (["--set", "nope=3"], "--set nope: the mission has no parameter 'nope'"),
    ],
)
def test_meaningless_run_flags_stop_before_the_run(argv: list[str], says: str) -> None:
    code, out, err = homing("run", WANDER, "--adapter", FAKE, "--no-view", "--until", "2 s", *argv)
    assert code == 2, out + err
    assert err.count("\n") == 1 and says in err, err
    assert "Traceback" not in err and "stopped:" not in out


@pytest.mark.parametrize(
    ("adapter", "says"),
    [
        ("os:getcwd", "--adapter os:getcwd: 'getcwd' cannot be called as getcwd(seed=N)"),
        ("tests.mission_fakes:NOT_A_FACTORY", "'NOT_A_FACTORY' is a int, not a factory CALLABLE(seed=N)"),
        ("tests.mission_fakes:make_nothing", "the factory returned a str, not a robot adapter (missing: clock, limits,"),
        ("tests.mission_fakes:make_robot_failing",
         "the factory failed: RuntimeError: the serial port /dev/ttyUSB0 is busy"),
        ("tests.mission_fakes:nope", "module tests.mission_fakes has no 'nope'"),
        ("no_such_module_here:make", "cannot import no_such_module_here: No module named 'no_such_module_here'"),
        (":make_robot", "needs MODULE:CALLABLE"),
        ("tests.mission_fakes:1x", "needs MODULE:CALLABLE"),
    ],
)
def test_an_adapter_that_is_not_a_robot_factory_is_one_line(adapter: str, says: str) -> None:
    code, out, err = homing("run", WANDER, "--adapter", adapter, "--no-view", "--until", "1 s")
    assert code == 2 and err.count("\n") == 1 and says in err, err


def _mission(tmp_path: Path, node: str, rate: str = "10", services: str = "[]") -> Path:
    path = tmp_path / "m.yaml"
    path.write_text(f"services: {services}\nrate: {rate}\nparams:\n  how_long: 2 s\ntree:\n  sequence:\n    - {node}\n")
    return path


@pytest.mark.parametrize(
    ("node", "value", "says"),
    [
        ("BackUp: {distance: -0.4}", "-0.4", "BackUp: 'distance' must be above 0 m, not -0.4 m"),
        ("BackUp: {distance: 40 cm, speed: 0 m/s}", "0 m/s", "BackUp: 'speed' must be above 0 m/s, not 0 m/s"),
        ("Spin: {omega: .inf}", ".inf", "Spin: 'omega' needs a finite number, not inf rad/s"),
        ("Spin: {angle: .nan}", ".nan", "Spin: 'angle' needs a number, not NaN"),
        ("Wait: -3 s", "-3 s", "Wait: 'seconds' must be at least 0 s, not -3 s"),
        ("BatteryBelow: {percent: 120}", "120", "BatteryBelow: 'percent' must be at most 100%, not 120%"),
        ("NavigateToPose: {x: 1, y: 2, xy_tolerance: 0}", "0}", "'xy_tolerance' must be above 0 m, not 0 m"),
        ("timeout: {seconds: 0, child: {Wait: 1}}", "0,", "timeout: 'seconds' must be above 0 s, not 0 s"),
        ("repeat: {times: -2, child: {Wait: 1}}", "-2,", "repeat: 'times' must be at least -1, not -2"),
    ],
)
def test_physically_meaningless_parameters_are_file_line_col_errors(tmp_path: Path, node: str, value: str,
                                                                   says: str) -> None:
    path = _mission(tmp_path, node)
    code, out, err = homing("check", str(path))
    line = path.read_text().splitlines()[6]
    assert code == 2 and "Traceback" not in err
    assert err.startswith(f"{path}:7:{line.index(value) + 1}: "), err  # at the value itself
    assert says in err and err.count("\n") == 1, err


def test_nan_is_accepted_where_it_means_not_given(tmp_path: Path) -> None:
    code, out, err = homing("check", str(_mission(tmp_path, "NavigateToPose: {theta: .nan}",
                                                           services="[grid_slam, navigation]")))
    assert code == 0, err  # x, y: nan = read the goal from the blackboard; theta: nan = any heading


@pytest.mark.parametrize(("rate", "says"), [("0.001", "rate: needs a number of Hz in 1 … 1000, not 0.001"),
                                            (".inf", "rate: needs a number of Hz in 1 … 1000, not inf")])
def test_a_mission_rate_out_of_range_is_a_file_line_col_error(tmp_path: Path, rate: str, says: str) -> None:
    code, out, err = homing("check", str(_mission(tmp_path, "Wait: 1", rate=rate)))
    assert code == 2 and err.startswith(f"{tmp_path / 'm.yaml'}:2:7: {says}"), err


def test_a_parameter_set_from_the_command_line_is_checked_where_it_is_used(tmp_path: Path) -> None:
    path = _mission(tmp_path, "Wait: $how_long")
    code, out, err = homing("check", str(path), "--set", "how_long=-5 min")
    assert code == 2 and err.startswith(f"{path}:7:13: Wait: 'seconds' must be at least 0 s, not -5 min"), err

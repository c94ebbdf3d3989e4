"""Output paths are checked before anything runs, and files are made with the user's usual permissions."""

from __future__ import annotations

import os
import stat
from collections.abc import Iterator
from pathlib import Path

import pytest
from homing.logs.runlog import Recorder
from homing.missions.cli import main

from homing.atomic import atomic_write
from homing.errors import UserError
from homing.outputs import check_output
from tests.conftest import REPO, homing_cli

WANDER = str(REPO / "missions" / "examples" / "wander.yaml")
FAKE = "tests.mission_fakes:make_robot"
RUN = ["run", WANDER, "--adapter", FAKE, "--no-view", "--until", "1 s"]  # ends by itself if a check were missed


def _unwritable_folder(tmp_path: Path) -> Path:
    """A folder no file can be made in: mode 0500 for a user; for root (who ignores modes), read-only sysfs."""
    if os.geteuid() != 0:
        folder = tmp_path / "locked"
        folder.mkdir()
        folder.chmod(0o500)
        return folder
    sysfs = Path("/sys")
    if not sysfs.is_dir() or os.access(sysfs, os.W_OK) and _can_create(sysfs):
        pytest.skip("running as root with no read-only folder to try")
    return sysfs


def _can_create(folder: Path) -> bool:
    try:
        (folder / ".homing-test").touch()
    except OSError:
        return False
    (folder / ".homing-test").unlink()
    return True


@pytest.fixture
def bad_paths(tmp_path: Path) -> dict[str, Path]:
    """Paths no output can go to, by reason."""
    a_file = tmp_path / "a_file"
    a_file.write_text("x")
    locked = _unwritable_folder(tmp_path)
    return {
        "is a folder": tmp_path,
        "is a file": a_file / "out.png",  # its parent folder is a file
        "cannot write in": locked / "out.png",
        "cannot make the folder": locked / "new" / "deeper" / "out.png",
    }


def test_check_output_names_the_option_and_the_reason(bad_paths: dict[str, Path], tmp_path: Path) -> None:
    for reason, path in bad_paths.items():
        with pytest.raises(UserError) as info:
            check_output(path, "--out")
        message = str(info.value)
        assert message.startswith(f"--out {path}: "), message
        assert reason.split()[0] in message and "\n" not in message, message
    ok = check_output(tmp_path / "new" / "folder" / "x.png", "--out")
    assert not ok.parent.exists(), "checking makes no folder"
    assert list(tmp_path.glob(".homing-probe*")) == [], "the probe is removed"
    with pytest.raises(UserError, match="needs a file path"):
        check_output("", "-o")


def _commands(bad: Path, tmp_path: Path) -> Iterator[list[str]]:
    """Every command and option that writes a file, pointed at ``bad``."""
    yield [*RUN, "--log", str(bad)]
    yield [*RUN, "--record", str(bad)]
    yield [*RUN, "--save-map", str(bad)]
    yield ["world", "show", "lab", "--out", str(bad)]
    yield ["map", "show", str(tmp_path / "m.yaml"), "--out", str(bad)]
    yield ["schema", "-o", str(bad)]
    yield ["replay", str(tmp_path / "run.hlog"), "--slam", "--json", str(bad)]
    yield ["replay", str(tmp_path / "run.hlog"), "--out", str(bad)]
    yield ["bench", "tick", "--json", str(bad)]
    yield ["bench", "explore", "--runs-json", str(bad)]
    yield ["bench", "persist", "--plot", str(bad)]
    yield ["bench", "dock", "--json", str(bad)]


def test_every_output_option_is_checked_before_anything_runs(bad_paths: dict[str, Path], tmp_path: Path,
                                                            capsys: pytest.CaptureFixture[str],
                                                            monkeypatch: pytest.MonkeyPatch) -> None:
    robot_log = tmp_path / "robot.json"
    monkeypatch.setenv("HOMING_FAKE_ROBOT_LOG", str(robot_log))
    for bad in bad_paths.values():
        for argv in _commands(bad, tmp_path):
            code, _, err = homing_cli(*argv)  # the arguments' types check them: before the command starts
            assert code == 2, (argv, err)
            assert err.count("\n") == 1 and "Traceback" not in err, (argv, err)
            assert str(bad.parent if bad.name == "out.png" else bad) in err, (argv, err)
    assert not robot_log.exists(), "no robot was built"
    code, _, err = homing_cli("bench", "explore", "--save-maps", str(bad_paths["is a file"].parent))
    assert code == 2 and "is a file" in err


@pytest.fixture
def umask() -> Iterator[None]:
    old = os.umask(0o022)
    yield
    os.umask(old)


@pytest.mark.usefixtures("umask")
def test_outputs_respect_the_umask(tmp_path: Path) -> None:
    for mask, mode in ((0o022, 0o644), (0o077, 0o600), (0o002, 0o664)):
        os.umask(mask)
        written = atomic_write(tmp_path / f"a{mask:o}.txt", "x")
        assert stat.S_IMODE(written.stat().st_mode) == mode
        rec = Recorder(tmp_path / f"r{mask:o}.hlog", {})
        rec.close()
        assert stat.S_IMODE((tmp_path / f"r{mask:o}.hlog").stat().st_mode) == mode
    os.umask(0o022)
    kept = tmp_path / "kept.txt"
    kept.write_text("old")
    kept.chmod(0o640)
    atomic_write(kept, "new")
    assert stat.S_IMODE(kept.stat().st_mode) == 0o640, "a replaced file keeps its mode"
    assert main(["schema", "-o", str(tmp_path / "s.json")]) == 0
    assert stat.S_IMODE((tmp_path / "s.json").stat().st_mode) == 0o644

"""SIGTERM and SIGHUP stop a run exactly as Ctrl-C does; the status log streams; a start-up interrupt is one line."""

from __future__ import annotations

import os
import shutil
import signal
import subprocess
import sys
import time
import uuid
from pathlib import Path

import pytest
from homing.logs.runlog import RunLog

from homing.map_server import FREE, load_map
from tests.conftest import REPO


def _default_sigint() -> None:
    # A shell without job control starts background jobs with SIGINT ignored, and homing rightly keeps a signal
    # it was started ignoring (as under nohup, which ignores SIGHUP); these tests are about the stop signals, so the
    # child starts with their defaults, however pytest itself was started (the SIGHUP case failed under nohup).
    signal.signal(signal.SIGINT, signal.SIG_DFL)
    signal.signal(signal.SIGHUP, signal.SIG_DFL)


def _homing(*args: str, env: dict[str, str] | None = None) -> subprocess.Popen[str]:
    return subprocess.Popen([sys.executable, "-m", "homing.missions.cli", *args], cwd=REPO, text=True,
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, env={**os.environ, **(env or {})},
                            preexec_fn=_default_sigint)


def _wait_for_line(path: Path, text: str, proc: subprocess.Popen[str], timeout: float = 120.0) -> list[str]:
    """The lines of ``path`` once one of them holds ``text``, read while ``proc`` still runs."""
    end = time.monotonic() + timeout
    while time.monotonic() < end:
        assert proc.poll() is None, proc.communicate()
        lines = path.read_text().splitlines() if path.exists() else []
        if any(text in line for line in lines):
            return lines
        time.sleep(0.05)
    raise AssertionError(f"'{text}' never appeared in {path}")


@pytest.mark.slow
@pytest.mark.parametrize("sig", [signal.SIGINT, signal.SIGTERM, signal.SIGHUP])
def test_a_stop_signal_stops_the_robot_and_writes_everything(sig: signal.Signals, tmp_path: Path) -> None:
    log, record, saved = tmp_path / "status.log", tmp_path / "run.hlog", tmp_path / "map.yaml"
    proc = _homing("run", "explore", "--world", "lab", "--seed", "1", "--no-view", "--speed", "4",
                   "--log", str(log), "--record", str(record), "--save-map", str(saved))
    # The status log is streamed: the robot's first moves are in the file while the run goes on.
    streamed = _wait_for_line(log, "SeedMap: INVALID -> RUNNING", proc)
    proc.send_signal(sig)
    out, err = proc.communicate(timeout=120)
    name = "Ctrl-C" if sig == signal.SIGINT else sig.name
    assert proc.returncode == 128 + sig, err
    assert "Traceback" not in err, err
    assert f"stopped: interrupted by {name} at t=" in out
    assert "final command v=0.000 m/s ω=0.000 rad/s (robot stopped)" in out
    lines = log.read_text().splitlines()
    assert lines[: len(streamed)] == streamed and all(line.startswith("[") for line in lines)
    assert lines[-1].endswith("-> INVALID"), "the tree was halted, and the halts logged"
    assert any("SeedMap: RUNNING -> INVALID" in line or "Explore: RUNNING -> INVALID" in line for line in lines)
    assert f"map saved: {saved}" in out
    assert (load_map(saved).grid == FREE).sum() > 100, "the map so far, with free space in it"
    run = RunLog(record)
    assert not run.truncated and run.damage is None
    assert run.commands()[-1][1].v == 0.0 and run.commands()[-1][1].omega == 0.0
    assert run.statuses()[-1][2] == "INVALID"


@pytest.mark.slow
def test_kill_9_keeps_every_status_line_written_and_the_run_log_up_to_its_last_second(tmp_path: Path) -> None:
    log, record = tmp_path / "status.log", tmp_path / "run.hlog"
    proc = _homing("run", "explore", "--world", "lab", "--seed", "1", "--no-view", "--speed", "4",
                   "--log", str(log), "--record", str(record))
    seen = _wait_for_line(log, "SeedMap: INVALID -> RUNNING", proc)
    proc.kill()
    proc.communicate(timeout=60)
    text = log.read_text()
    assert text.endswith("\n") and text.splitlines()[: len(seen)] == seen, "whole lines, nothing lost"
    last_change = float(text.splitlines()[-1][1:].split("s]")[0])
    run = RunLog(record)  # readable: a torn last frame at most
    assert run.damage is None
    assert run.end >= last_change - 1.0 - 0.1, "at most the last second (and a tick) of the run log is lost"


@pytest.mark.parametrize("sig", ["SIGINT", "SIGTERM"])
def test_a_stop_during_start_up_is_one_line(sig: str, tmp_path: Path) -> None:
    proc = _homing("run", str(REPO / "missions/examples/wander.yaml"), "--adapter",
                   "tests.mission_fakes:make_robot_interrupted", "--log", str(tmp_path / "s.log"),
                   env={"HOMING_FAKE_SIGNAL": sig})
    out, err = proc.communicate(timeout=60)
    assert proc.returncode == 128 + getattr(signal, sig)
    name = "Ctrl-C" if sig == "SIGINT" else sig
    assert err == f"homing run: interrupted by {name} before it finished\n"
    assert out == ""


@pytest.mark.tmux
@pytest.mark.slow
@pytest.mark.skipif(shutil.which("tmux") is None, reason="tmux is not installed (.ci/run installs it)")
def test_a_terminal_that_hangs_up_loses_nothing(tmp_path: Path) -> None:
    """The live view's terminal closes under the run (an ssh drop): SIGHUP, and writes to it fail; all is saved."""
    log, record, saved, err = (tmp_path / n for n in ("status.log", "run.hlog", "map.yaml", "err.txt"))
    session = f"homing-{uuid.uuid4().hex[:8]}"
    command = (f"cd {REPO} && {sys.executable} -m homing.missions.cli run explore --world lab --seed 1 --speed 20 "
               f"--log {log} --record {record} --save-map {saved} 2> {err}")
    subprocess.run(["tmux", "new-session", "-d", "-s", session, "-x", "80", "-y", "24", command], check=True)
    try:
        end = time.monotonic() + 120
        while not (log.exists() and "SeedMap: INVALID -> RUNNING" in log.read_text()):
            assert time.monotonic() < end, "the run never got going"
            time.sleep(0.05)
    finally:
        subprocess.run(["tmux", "kill-session", "-t", session], capture_output=True)  # the terminal goes away
    end = time.monotonic() + 120
    while not saved.exists():
        assert time.monotonic() < end, "the map was never saved"
        time.sleep(0.05)
    assert (load_map(saved).grid == FREE).sum() > 100
    assert log.read_text().splitlines()[-1].endswith("-> INVALID"), "the tree was halted and the halts logged"
    run = RunLog(record, salvage=True)
    assert run.damage is None and run.commands()[-1][1].v == 0.0
    assert "Traceback" not in err.read_text()


def _start_then_wait(folder: str, i: int) -> int:
    """A sweep's run: marks that it started (with its process id); all but the first then wait up to 120 s for a
    file nobody writes."""
    # Written whole or not at all: a worker stopped between creating the file and writing its id left it empty.
    Path(folder, f"writing_{i}").write_text(str(os.getpid()))
    os.replace(Path(folder, f"writing_{i}"), Path(folder, f"started_{i}"))
    if i > 0:
        deadline = time.monotonic() + 120.0
        while time.monotonic() < deadline and not Path(folder, "never").exists():
            time.sleep(0.05)
        Path(folder, f"finished_{i}").touch()
    return i


@pytest.mark.parametrize("engine", ["pool", "ray"])
def test_a_stopped_sweep_stops_its_workers_and_starts_no_more_runs(engine: str, tmp_path: Path) -> None:
    """``bench explore --workers 2`` sent SIGTERM went on with every queued run (minutes each) before it exited: the
    process pool waited for them, and a signal sent to the bench alone never reaches its workers. Stopped (the CLI
    makes Ctrl-C and SIGTERM a KeyboardInterrupt) as its first run ends, a sweep ends its runs there. On a local
    Ray (``--engine ray``) the runs in flight are cancelled, their workers killed, before it returns."""
    if engine == "ray":
        pytest.importorskip("ray", reason="Ray is the optional extra homing[ray]")
    from homing.benchmarks.engine import Engine, run_jobs

    jobs = [(str(tmp_path), i) for i in range(8)]

    def stop(_outcome: object) -> None:
        raise KeyboardInterrupt

    with pytest.raises(KeyboardInterrupt):
        run_jobs(_start_then_wait, jobs, Engine(engine, workers=2), stop)
    started = list(tmp_path.glob("started_*"))
    assert 1 <= len(started) < len(jobs)
    for f in started:  # every worker that ran one is gone, not finishing its run in the background
        if engine == "ray" and f.name == "started_0":
            continue  # the first run's worker, done, may idle in Ray's pool (the shutdown ends it in the background)
        with pytest.raises(ProcessLookupError):
            os.kill(int(f.read_text()), 0)
    assert not list(tmp_path.glob("finished_*")), "a run went on after the sweep was stopped"

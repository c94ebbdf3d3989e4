"""Following a run from another terminal: ``homing run … --serve`` streams the tree, ``homing view --attach`` draws it.

A real run in a subprocess serves on a free port; the follower connects over
TCP, must see the live view's frames (the mission's header and tree), every
node's status, and a last snapshot saying how the run ended, with the same
root status the run reports. Nothing listening is a one-line error.
"""

from __future__ import annotations

import os
import re
import subprocess
import sys

import pytest
from homing.missions.cli import main
from homing.missions.remote import messages, parse_address

from tests.conftest import REPO


def test_a_follower_sees_the_run_to_its_end() -> None:
    env = {**os.environ, "PYTHONPATH": str(REPO)}
    proc = subprocess.Popen(
        [sys.executable, "-m", "homing.missions.cli", "run", "wander", "--adapter", "tests.mission_fakes:make_robot",
         "--serve", "0", "--speed", "5", "--until", "8s", "--no-view"],
        cwd=REPO, env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
    )  # fmt: skip
    try:
        assert proc.stderr is not None
        line = proc.stderr.readline()
        m = re.search(r"serving the tree on ([\d.]+):(\d+)", line)
        assert m, line
        got = list(messages(m.group(1), int(m.group(2)), size=(80, 24)))
        out, _ = proc.communicate(timeout=60)
    finally:
        proc.kill()
    assert proc.returncode == 0, out
    assert len(got) >= 3, "several snapshots while the run goes on"
    assert got[-1]["ended"] and got[-1]["root"] == "INVALID", "a time limit halts the tree"
    assert "stopped: time_limit" in out
    frame = got[len(got) // 2]["frame"]
    assert "wander" in frame and "Lifecycle" in frame and "\x1b[" in frame, "the live view's frame, in colour"
    assert max(len(re.sub(r"\x1b\[[0-9;]*m", "", line)) for line in frame.splitlines()) <= 80
    names = {n["name"] for n in got[0]["nodes"]}
    assert "Lifecycle" in names and got[0]["nodes"][0]["depth"] == 0
    times = [g["time"] for g in got]
    assert times == sorted(times) and times[-1] == pytest.approx(8.0, abs=0.2)


def test_attach_with_nothing_listening_is_one_line(capsys: pytest.CaptureFixture[str]) -> None:
    import socket

    with socket.socket() as s:  # a port that was free a moment ago, and nobody listens on
        s.bind(("127.0.0.1", 0))
        port = s.getsockname()[1]
    assert main(["view", "--attach", f"127.0.0.1:{port}"]) == 2
    err = capsys.readouterr().err
    assert err == f"--attach 127.0.0.1:{port}: nothing is listening there (start a run with 'homing run MISSION --world W --serve PORT')\n"


@pytest.mark.parametrize(("text", "want"), [("8765", ("127.0.0.1", 8765)), ("0.0.0.0:1", ("0.0.0.0", 1)),
                                            ("[::1]:80", ("::1", 80))])
def test_addresses(text: str, want: tuple[str, int]) -> None:
    assert parse_address(text) == want


@pytest.mark.parametrize("text", ["http", "1:2:x", "70000"])
def test_bad_addresses(text: str) -> None:
    with pytest.raises(ValueError):
        parse_address(text)

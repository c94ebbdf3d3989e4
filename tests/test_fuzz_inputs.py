"""Random bytes and random YAML, fed to every command that reads a file: one-line errors, never a traceback.

Each command runs in this process (``homing_cli``): anything but a
``UserError`` (printed, exit 2) or a clean run would escape ``main`` and
fail the example with its traceback.
"""

from __future__ import annotations

import tempfile
from pathlib import Path

import yaml
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from tests.conftest import homing_cli
from tests.test_mission_check import yaml_values

WORLD_KEYS = ["name", "doc", "map", "dock", "dock_tag", "start", "tags", "patches", "battery", "faults", "wall_height",
              "image", "resolution", "origin", "negate", "occupied_thresh", "free_thresh", "x", "y", "yaw", "auto",
              "tree", "services", "params", "subtrees", "include", "rate", "view", "mission"]
documents = st.one_of(
    yaml_values,
    st.dictionaries(st.sampled_from(WORLD_KEYS), yaml_values, max_size=5),
)
FAKE = "tests.mission_fakes:make_robot"


def _commands(path: Path, out: Path) -> list[list[str]]:
    """Every command that reads ``path`` (short runs: a file that happens to be a mission stops at once)."""
    return [
        ["check", str(path)],
        ["view", str(path)],
        ["schema", str(path)],
        ["missions", str(path)],
        ["run", str(path), "--adapter", FAKE, "--no-view", "--until", "0.3 s"],
        ["world", "show", str(path), "--out", str(out / "w.png")],
        ["map", "show", str(path), "--out", str(out / "m.png")],
        ["replay", str(path), "--slam"],
    ]


def _feed(name: str, data: bytes, extra: dict[str, bytes] | None = None) -> None:
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp)
        path = folder / name
        path.write_bytes(data)
        for other, body in (extra or {}).items():
            (folder / other).write_bytes(body)
        for argv in _commands(path, folder):
            code, out, err = homing_cli(*argv)
            assert code in (0, 1, 2), (argv, code, err)
            assert "Traceback" not in out + err
            if code == 2:
                assert err.strip(), f"{argv}: exit 2 must say why"


@settings(max_examples=40, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(data=st.binary(max_size=300), name=st.sampled_from(["f.yaml", "f.hlog", "f.log", "f.pgm"]))
def test_random_bytes(data: bytes, name: str) -> None:
    _feed(name, data)


@settings(max_examples=40, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(doc=documents)
def test_random_yaml(doc: object) -> None:
    _feed("f.yaml", yaml.safe_dump(doc, allow_unicode=True).encode())


@settings(max_examples=30, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(image=st.binary(max_size=200), header=st.sampled_from([b"", b"P5\n", b"P5\n3 2\n255\n", b"P2\n2 2\n15\n",
                                                              b"P5\n99999 99999\n255\n", b"\x89PNG\r\n\x1a\n"]))
def test_random_map_images(image: bytes, header: bytes) -> None:
    doc = b"image: m.pgm\nresolution: 0.05\norigin: [0, 0, 0]\n"
    _feed("f.yaml", doc, {"m.pgm": header + image})


@settings(max_examples=30, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(frames=st.binary(max_size=300), version=st.sampled_from([b"1", b"2", b"0", b"x"]))
def test_random_run_log_frames(frames: bytes, version: bytes) -> None:
    _feed("f.hlog", b"HOMINGLOG " + version + b"\n" + frames)

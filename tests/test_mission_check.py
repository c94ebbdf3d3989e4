"""`homing check`: every mistake reported as file:line:col, with suggestions, exit 2, never a traceback."""

from __future__ import annotations

import contextlib
import io
import re
import subprocess
import sys
import tempfile
from pathlib import Path

import pytest
from homing.behaviours.registry import NODES
from homing.missions.cli import main
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from tests.conftest import REPO

EXAMPLES = REPO / "missions" / "examples"
ERROR_LINE = re.compile(r"^(?P<file>.+?):(?P<line>\d+):(?P<col>\d+): (?P<msg>.+)$")


def check(path: Path) -> tuple[int, str, str]:
    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        code = main(["check", str(path)])
    return code, out.getvalue(), err.getvalue()


def write(tmp: Path, text: str, name: str = "m.yaml") -> Path:
    path = tmp / name
    path.write_text(text)
    return path


def errors(tmp: Path, text: str, **files: str) -> list[tuple[int, int, str]]:
    for name, body in files.items():
        write(tmp, body, name)
    code, _, err = check(write(tmp, text))
    assert code == 2, err
    out = []
    for line in err.splitlines():
        m = ERROR_LINE.match(line)
        assert m, f"not file:line:col: {line!r}"
        out.append((int(m["line"]), int(m["col"]), m["msg"]))
    return out


HEAD = "services: []\n"


@pytest.mark.parametrize("example", sorted(EXAMPLES.glob("*.yaml")), ids=lambda p: p.name)
def test_bundled_examples_check_clean(example: Path) -> None:
    code, out, err = check(example)
    assert code == 0, err
    assert out.count("\n") == 1 and ": ok: mission" in out


def test_reports_every_error_with_position_and_suggestion(tmp_path: Path) -> None:
    text = HEAD + (
        "tree:\n"
        "  sequence:\n"
        "    - Wiat: {seconds: 2}\n"        # line 4: unknown node
        "    - Wait: {secnds: 2}\n"         # line 5: misspelt parameter (+ missing required)
        "    - Wait: {seconds: 5 m}\n"      # line 6: wrong unit
        "    - retry: {attempts: two, child: Stop}\n"  # line 7: wrong type
        "    - timeout: {seconds: 3}\n"     # line 8: missing child
    )  # fmt: skip
    got = errors(tmp_path, text)
    assert (4, 7, "unknown node 'Wiat' (did you mean 'Wait'?)") in got
    assert any(line == 5 and col == 14 and "did you mean 'seconds'" in msg for line, col, msg in got)
    assert any(line == 5 and "missing the required parameter 'seconds'" in msg for line, _, msg in got)
    assert any(line == 6 and col == 23 and "wrong unit 'm'" in msg for line, col, msg in got)
    assert any(line == 7 and "'attempts' needs an integer" in msg for line, _, msg in got)
    assert any(line == 8 and "needs 'child:'" in msg for line, _, msg in got)
    assert len(got) == 6


def test_blackboard_key_nobody_writes(tmp_path: Path) -> None:
    text = HEAD + (
        "tree:\n  sequence:\n"
        "    - SetBlackboard: {key: /a, value: 1}\n"
        "    - CheckBlackboard: {key: /a, value: 1}\n"
        "    - CheckBlackboard: {key: /b, value: 1}\n"
    )
    got = errors(tmp_path, text)
    assert len(got) == 1 and got[0][0] == 6 and "reads '/b' but nothing writes it" in got[0][2]


def test_include_cycle_unknown_include_and_subtree(tmp_path: Path) -> None:
    text = HEAD + "include: [a.yaml, missing.yaml]\ntree:\n  sequence: [A, Nope]\n"
    got = errors(tmp_path, text, **{
        "a.yaml": "include: [b.yaml]\nsubtrees:\n  A: {tree: Stop}\n",
        "b.yaml": "include: a.yaml\n",
    })  # fmt: skip
    msgs = [m for _, _, m in got]
    assert any("include cycle: a.yaml → b.yaml → a.yaml" in m for m in msgs)
    assert any("unknown include 'missing.yaml'" in m for m in msgs)
    assert any("unknown node 'Nope'" in m for m in msgs)
    assert len(got) == 3


def test_duplicate_names_and_subtree_parameters(tmp_path: Path) -> None:
    text = HEAD + (
        "subtrees:\n"
        "  Pause: {params: {t: null}, tree: {Wait: {seconds: $t}}}\n"
        "tree:\n  sequence:\n    children:\n"
        "      - Stop: {name: X}\n"
        "      - Stop: {name: X}\n"
        "      - Pause: {tt: 1}\n"
        "      - Pause: {t: 2 s}\n"
    )
    got = errors(tmp_path, text)
    msgs = [(line, m) for line, _, m in got]
    assert any(line == 8 and "duplicate name 'X'" in m for line, m in msgs)
    assert any(line == 9 and "unknown parameter 'tt' of subtree 'Pause' (did you mean 't'?)" in m for line, m in msgs)
    assert any(line == 9 and "missing the required parameter 't'" in m for line, m in msgs)
    assert len(got) == 3


def test_unregistered_service_is_a_clear_error(tmp_path: Path) -> None:
    got = errors(tmp_path, "services: [navigatoin]\ntree: Stop\n")
    assert any("unknown service 'navigatoin'" in m and "did you mean 'navigation'" in m for _, _, m in got), got


def test_a_name_with_a_line_break_still_gives_one_error_line(tmp_path: Path) -> None:
    """Found by test_random_missions_never_raise: a service named "\r" split the report in two."""
    path = write(tmp_path, 'services: ["\\r"]\ntree: Stop\n')
    code, _, err = check(path)
    assert code == 2
    lines = err.splitlines()
    assert len(lines) == 1 and ERROR_LINE.match(lines[0]), err
    assert "unknown service '\\r'" in lines[0]


def test_parameter_substitution_and_units(tmp_path: Path) -> None:
    from homing.missions.compiler import compile_mission

    path = write(tmp_path, HEAD + "params: {t: 1.5 min}\ntree:\n  sequence: [{Wait: {seconds: $t}}, {timeout: {seconds: 250 ms, child: Stop}}]\n")
    mission = compile_mission(path)
    waits = {i.spec: i.params for i in mission.info.values()}
    assert waits["Wait"]["seconds"] == pytest.approx(90.0)
    assert waits["timeout"]["seconds"] == pytest.approx(0.25)
    mission = compile_mission(path, {"t": 7})
    assert next(i.params for i in mission.info.values() if i.spec == "Wait")["seconds"] == 7.0


def test_cli_check_is_one_line_per_error_and_no_traceback(tmp_path: Path) -> None:
    path = write(tmp_path, HEAD + "tree:\n  sequense: [Stop]\n")
    out = subprocess.run([sys.executable, "-m", "homing.missions.cli", "check", str(path)], capture_output=True, text=True, timeout=60)
    assert out.returncode == 2
    assert out.stderr == f"{path}:3:3: unknown node 'sequense' (did you mean 'sequence'?)\n"


# --------------------------------------------------------------------------- properties

BASE = (EXAMPLES / "wander.yaml").read_text()
NAMES = sorted(NODES) + ["children", "child", "seconds", "name", "$side_time", "subtrees", "tree", "params"]
scalars = st.one_of(st.none(), st.booleans(), st.integers(-5, 5), st.floats(allow_nan=True), st.sampled_from(NAMES),
                    st.text(max_size=6), st.sampled_from(["2 s", "5 m", "$x", "$$y", "90 deg/s"]))  # fmt: skip
yaml_values = st.recursive(
    scalars,
    lambda inner: st.one_of(st.lists(inner, max_size=4), st.dictionaries(st.sampled_from(NAMES), inner, max_size=3)),
    max_leaves=20,
)


def _assert_clean(tmp: Path, path: Path) -> None:
    code, out, err = check(path)
    assert code in (0, 2)
    assert "Traceback" not in out + err
    if code == 0:
        assert ": ok: mission" in out
        return
    assert err.strip(), "exit 2 must say why"
    for line in err.splitlines():
        m = ERROR_LINE.match(line)
        assert m, f"not file:line:col: message: {line!r}"
        file = Path(m["file"])
        assert file.is_file(), line
        n_lines = len(file.read_text().splitlines())
        assert 1 <= int(m["line"]) <= n_lines + 1 and int(m["col"]) >= 1, line


@settings(max_examples=120, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(st.lists(st.tuples(st.integers(0, len(BASE)), st.integers(0, 12), st.text(alphabet=" :-{}[]$\n\t#abWait0123'\"", max_size=6)), min_size=1, max_size=4))
def test_mangled_missions_never_raise(edits: list[tuple[int, int, str]]) -> None:
    text = BASE
    for pos, cut, insert in edits:
        pos = min(pos, len(text))
        text = text[:pos] + insert + text[pos + cut:]
    with tempfile.TemporaryDirectory() as tmp:
        path = write(Path(tmp), text)
        _assert_clean(Path(tmp), path)


@settings(max_examples=120, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(tree=yaml_values, extra=st.dictionaries(st.sampled_from(["params", "subtrees", "include", "rate", "services", "view", "tre"]), yaml_values, max_size=3))
def test_random_missions_never_raise(tree: object, extra: dict[str, object]) -> None:
    import yaml

    doc = {"services": [], "tree": tree, **extra}
    with tempfile.TemporaryDirectory() as tmp:
        path = write(Path(tmp), yaml.safe_dump(doc, allow_unicode=True))
        _assert_clean(Path(tmp), path)


def test_bundled_missions_resolve_by_name(tmp_path, monkeypatch) -> None:
    from homing.missions.loader import BUNDLED, resolve_mission

    monkeypatch.chdir(tmp_path)
    assert resolve_mission("wander") == BUNDLED / "examples" / "wander.yaml"
    assert resolve_mission("wander.yaml") == BUNDLED / "examples" / "wander.yaml"
    # A user's own file of the same name wins over the bundled one.
    (tmp_path / "wander.yaml").write_text("tree: Succeed\n")
    assert resolve_mission("wander.yaml") == Path("wander.yaml")
    # An unknown name stays as given, so the error names what the user typed.
    assert resolve_mission("nope") == Path("nope")

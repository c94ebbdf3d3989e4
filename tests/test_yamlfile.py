"""YAML mistakes are reported where a person looks for them: an unclosed bracket or quote where it opens."""

from __future__ import annotations

import pytest

from homing.errors import UserError
from homing.yamlfile import loads


@pytest.mark.parametrize(
    ("text", "where", "char", "gave_up"),
    [
        ("rate: 10\nservices: [grid_slam, navigation\ntree: Wait\n", "m.yaml:2:11:", "'['", "line 3, column 5"),
        ("params: {a: 1, b: 2\n\n\ntree: Wait\n", "m.yaml:1:9:", "'{'", "line 4, column 5"),
        ('doc: "explore\nrate: 10\n', "m.yaml:1:6:", "'\"'", "line 3, column 1"),
        ("doc: 'explore\nrate: 10\n", "m.yaml:1:6:", '"\'"', "line 3, column 1"),
        ("tree:\n  sequence: [Wait, {Spin: {angle: 3}]\n", "m.yaml:2:20:", "'{'", "line 2, column 37"),
        ("services: [\n", "m.yaml:1:11:", "'['", "line 2, column 1"),
    ],
)
def test_an_unclosed_bracket_or_quote_is_reported_where_it_opens(text: str, where: str, char: str, gave_up: str) -> None:
    with pytest.raises(UserError) as info:
        loads(text, "m.yaml")
    message = str(info.value)
    assert message.startswith(f"{where} invalid YAML: this {char} is never closed"), message
    assert f"the parser gave up at {gave_up}" in message
    assert "\n" not in message


@pytest.mark.parametrize(
    ("text", "where", "problem"),
    [
        ("a:\n  - b\n - c\n", "m.yaml:3:2:", "expected <block end>"),  # bad indentation: where it goes wrong
        ("a: b: c\n", "m.yaml:1:5:", "mapping values are not allowed here"),
        ("a: [1, 2]]\n", "m.yaml:1:10:", "found ']'"),  # one bracket too many: at the extra one
    ],
)
def test_other_mistakes_stay_where_the_parser_stopped(text: str, where: str, problem: str) -> None:
    with pytest.raises(UserError) as info:
        loads(text, "m.yaml")
    assert str(info.value).startswith(f"{where} invalid YAML:") and problem in str(info.value)
    assert "never closed" not in str(info.value)

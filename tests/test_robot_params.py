"""A robot's parameters (``cloudnav_core.params``): one object, its defaults documented
once in the README."""

from __future__ import annotations

import ast
import dataclasses
import re
from pathlib import Path
from typing import Any

from cloudnav_core.params import RobotConfig

README = Path(__file__).resolve().parent.parent / "README.md"
ROW = re.compile(r"^\| `([a-z0-9_.]+)` \| (.+?) \| .+ \|$")


def defaults(instance: Any, prefix: str = "") -> dict[str, Any]:
    """Every leaf field of a nested dataclass, by dotted name."""
    found: dict[str, Any] = {}
    for field in dataclasses.fields(instance):
        value = getattr(instance, field.name)
        if dataclasses.is_dataclass(value):
            found |= defaults(value, f"{prefix}{field.name}.")
        else:
            found[prefix + field.name] = value
    return found


def documented() -> dict[str, Any]:
    """The README's "Robot parameters" table, values read as Python literals."""
    section = README.read_text().split("### Robot parameters", 1)[1].split("\n#", 1)[0]
    rows = (ROW.match(line) for line in section.splitlines())
    return {row[1]: _literal(row[2]) for row in rows if row is not None}


def _literal(text: str) -> Any:
    text = text.strip("`")
    try:
        return ast.literal_eval(text)
    except (ValueError, SyntaxError):
        return text


def test_the_readme_lists_every_default_as_the_code_has_it():
    assert documented() == defaults(RobotConfig())


def test_the_planner_keeps_its_margin_beyond_the_body():
    config = RobotConfig()
    assert config.planning_radius == config.body.radius + config.planner.margin

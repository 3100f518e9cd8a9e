"""Runtime requirements are runtime requirements: every distribution the server's own code
imports (``cloudnav_core``, ``maps``, ``robots``, ``telemetry``, ``cloudnav_web``, tests
and benchmarks aside) is pinned in ``requirements.txt``'s runtime section, above ``# Tests,
lint and benchmarks`` (issue 24 point 6)."""

from __future__ import annotations

import ast
import importlib.metadata
import re
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
PRODUCT = ("cloudnav_core", "maps", "robots", "telemetry", "cloudnav_web")
TEST_SECTION = "# Tests, lint and benchmarks"


def _normal(name: str) -> str:
    return re.sub(r"[-_.]+", "-", name).lower()


def runtime_pins(text: str) -> set[str]:
    """The distributions pinned above the test section of a requirements file."""
    runtime = text.split(TEST_SECTION)[0]
    found = (re.match(r"^([A-Za-z0-9_.\-]+)(\[.*\])?==", line) for line in runtime.splitlines())
    return {_normal(match[1]) for match in found if match}


def top_level_imports(path: Path) -> set[str]:
    """The top-level module names a source file imports, at any depth of its code."""
    names: set[str] = set()
    for node in ast.walk(ast.parse(path.read_text(), filename=str(path))):
        if isinstance(node, ast.Import):
            names |= {alias.name.split(".")[0] for alias in node.names}
        elif isinstance(node, ast.ImportFrom) and node.level == 0 and node.module:
            names.add(node.module.split(".")[0])
    return names


def distributions_imported(paths: list[Path], root: Path = ROOT) -> dict[str, set[str]]:
    """Distributions installed in this virtualenv (normalised) imported by ``paths``, each
    with its files. The ROS 1 client libraries the robot's ROS backend imports come from
    Debian's packages (``scripts/setup.sh``; on a robot, its ROS install), not from PyPI:
    tests of that backend put Debian's ``dist-packages`` on ``sys.path``, so they are
    left out by where they are installed, not by name."""
    venv = [entry for entry in sys.path if entry.startswith(sys.prefix)]
    owners: dict[str, list[str]] = {}
    for dist in importlib.metadata.distributions(path=venv):
        for module in _top_level_names(dist):
            owners.setdefault(module, []).append(dist.metadata["Name"])
    found: dict[str, set[str]] = {}
    for path in paths:
        for module in top_level_imports(path) - set(sys.stdlib_module_names) - set(PRODUCT):
            for name in owners.get(module, []):
                found.setdefault(_normal(name), set()).add(str(path.relative_to(root)))
    return found


def _top_level_names(dist: importlib.metadata.Distribution) -> set[str]:
    """The importable top-level names a distribution installs."""
    listed = dist.read_text("top_level.txt")
    if listed:
        return set(listed.split())
    return {
        Path(str(file)).parts[0].removesuffix(".py")
        for file in dist.files or []
        if not str(file).startswith("..") and ".dist-info" not in str(file)
    }


def _product_files() -> list[Path]:
    return [path for app in PRODUCT for path in sorted((ROOT / app).rglob("*.py"))]


def test_every_distribution_the_server_imports_is_a_runtime_requirement() -> None:
    runtime = runtime_pins((ROOT / "requirements.txt").read_text())
    imported = distributions_imported(_product_files())
    missing = {dist: sorted(files)[:3] for dist, files in imported.items() if dist not in runtime}
    assert missing == {}, f"imported by the product but not a runtime requirement: {missing}"


def test_the_check_sees_a_test_only_requirement_imported_by_the_product(tmp_path: Path) -> None:
    """The check above would catch what it looks for (it must not pass vacuously)."""
    probe = tmp_path / "probe.py"
    probe.write_text("import os, maps.models\ndef read():\n    from mcap.reader import X\n")
    text = "Django==5.2.19\n" + TEST_SECTION + "\nmcap==1.6.0\n"
    assert distributions_imported([probe], tmp_path) == {"mcap": {"probe.py"}}
    assert runtime_pins(text) == {"django"}

"""Apps use each other only through public names: no module imports a name (or a module)
starting with ``_`` from another app. A private name is free to change with its module;
what another app needs is made public where it lives (issue 10)."""

from __future__ import annotations

import ast
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
APPS = ("cloudnav_core", "cloudnav_django", "maps", "robots", "telemetry", "cloudnav_web")


def _private(dotted: str) -> bool:
    return any(part.startswith("_") and part != "__init__" for part in dotted.split("."))


def _cross_app_private_imports(path: Path, app: str, root: Path = ROOT) -> list[str]:
    found = []
    for node in ast.walk(ast.parse(path.read_text(), filename=str(path))):
        if isinstance(node, ast.ImportFrom) and node.level == 0 and node.module:
            target = node.module.split(".")[0]
            if target in APPS and target != app:
                names = [node.module] + [f"{node.module}.{a.name}" for a in node.names]
                found += [
                    f"{path.relative_to(root)}:{node.lineno} {n}" for n in names if _private(n)
                ]
        elif isinstance(node, ast.Import):
            for alias in node.names:
                target = alias.name.split(".")[0]
                if target in APPS and target != app and _private(alias.name):
                    found.append(f"{path.relative_to(root)}:{node.lineno} {alias.name}")
    return sorted(set(found))


def test_no_app_imports_a_private_name_of_another() -> None:
    offending = [
        line
        for app in APPS
        for path in sorted((ROOT / app).rglob("*.py"))
        for line in _cross_app_private_imports(path, app)
    ]
    assert offending == [], "private names imported across apps:\n" + "\n".join(offending)


def test_the_check_sees_a_private_import(tmp_path: Path) -> None:
    """The walk above would catch what it looks for (it must not pass vacuously)."""
    probe = tmp_path / "probe.py"
    probe.write_text("from cloudnav_web.pages import _hidden\nimport maps._secret\n")
    assert _cross_app_private_imports(probe, "telemetry", tmp_path) == [
        "probe.py:1 cloudnav_web.pages._hidden",
        "probe.py:2 maps._secret",
    ]
    assert _cross_app_private_imports(probe, "maps", tmp_path) == [
        "probe.py:1 cloudnav_web.pages._hidden"
    ]

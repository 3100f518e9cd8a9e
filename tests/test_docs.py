"""The repository carries its own documentation, and it says what the code does: the README
names every variable ``make demo`` reads and links only to files that exist; the design
document lists every topic a robot has."""

from __future__ import annotations

import re
from pathlib import Path

from cloudnav_core.topics import ROBOT_TOPIC_TYPES

ROOT = Path(__file__).resolve().parent.parent
README = (ROOT / "README.md").read_text()
DESIGN = ROOT / "docs" / "design.md"


def test_the_readme_names_every_variable_make_demo_reads() -> None:
    script = (ROOT / "scripts" / "demo.sh").read_text()
    variables = set(re.findall(r"\$\{([A-Z_]+):-", script))
    assert {"HOST", "PORT", "ROBOTS", "CLOUDNAV_PUBLIC_URL", "CLOUDNAV_DEMO_PASSWORD"} <= variables
    missing = {name for name in variables if f"`{name}`" not in README}
    assert not missing


def test_the_readme_links_only_to_files_in_the_repository() -> None:
    targets = re.findall(r"\]\(([^)#]+)(?:#[^)]*)?\)", README)
    local = [t for t in targets if not re.match(r"[a-z]+://", t)]
    assert "docs/design.md" in local
    assert all((ROOT / target).exists() for target in local), local
    assert "../shared" not in README


def test_the_design_document_lists_every_robot_topic_with_its_type() -> None:
    design = DESIGN.read_text()
    for topic, message_type in ROBOT_TOPIC_TYPES.items():
        assert f"`/r/{topic}` | {message_type}" in design, topic

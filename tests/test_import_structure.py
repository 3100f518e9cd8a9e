"""The project's import graph, every import counted: those inside functions and those made
only for type checking too (import-linter's contracts in pyproject.toml keep the layers;
this keeps modules from importing each other round in a circle).

One circle is left, and may only shrink: the rosbridge hub, the relay between processes,
the access review and revocation, and the camera index, which reach each other through
imports inside functions and for type checking. Any other circle fails."""

from __future__ import annotations

import grimp
import networkx as nx
import pytest

PACKAGES = ("cloudnav_core", "cloudnav_web", "maps", "robots", "telemetry")

HUB_CIRCLE = frozenset(
    {
        "telemetry.access.review",
        "telemetry.rosbridge.hub",
        "telemetry.rosbridge.relay",
        "telemetry.access.revocation",
        "telemetry.video.cameras",
    }
)


@pytest.fixture(scope="module")
def imports() -> nx.DiGraph:
    graph = grimp.build_graph(*PACKAGES, include_external_packages=False)
    edges = nx.DiGraph()
    for module in graph.modules:
        for imported in graph.find_modules_directly_imported_by(module):
            edges.add_edge(module, imported)
    return edges


def test_no_modules_import_each_other_round_in_a_circle_but_the_hubs(
    imports: nx.DiGraph,
) -> None:
    circles = [c for c in nx.strongly_connected_components(imports) if len(c) > 1]
    unexpected = [sorted(c) for c in circles if not c <= HUB_CIRCLE]
    assert not unexpected, f"import circles: {unexpected}"


def test_the_graph_is_read_whole(imports: nx.DiGraph) -> None:
    # The circle above is found, so imports inside functions are counted.
    assert imports.has_edge("telemetry.access.revocation", "telemetry.rosbridge.hub")
    assert imports.number_of_nodes() > 150

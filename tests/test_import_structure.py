"""The project's import graph, every import counted: those inside functions and those made
only for type checking too (import-linter's contracts in pyproject.toml keep the layers;
this keeps modules from importing each other round in a circle, and packages from
importing each other both ways: none may)."""

from __future__ import annotations

from collections import defaultdict

import grimp
import networkx as nx
import pytest

PACKAGES = ("cloudnav_core", "cloudnav_django", "cloudnav_web", "maps", "robots", "telemetry")


@pytest.fixture(scope="module")
def imports() -> nx.DiGraph:
    graph = grimp.build_graph(*PACKAGES, include_external_packages=False)
    edges = nx.DiGraph()
    for module in graph.modules:
        for imported in graph.find_modules_directly_imported_by(module):
            edges.add_edge(module, imported)
    return edges


def test_no_modules_import_each_other_round_in_a_circle(imports: nx.DiGraph) -> None:
    circles = [sorted(c) for c in nx.strongly_connected_components(imports) if len(c) > 1]
    assert not circles, f"import circles: {circles}"


def test_no_two_packages_import_each_other_both_ways(imports: nx.DiGraph) -> None:
    between: defaultdict[tuple[str, str], list[str]] = defaultdict(list)
    for importer, imported in imports.edges:
        pair = (importer.split(".")[0], imported.split(".")[0])
        if pair[0] != pair[1]:
            between[pair].append(f"{importer} -> {imported}")
    both_ways = {
        f"{a} -> {b}": sorted(found) for (a, b), found in between.items() if (b, a) in between
    }
    assert not both_ways, (
        f"packages importing each other both ways, each way's imports: {both_ways}"
    )


def test_the_graph_is_read_whole(imports: nx.DiGraph) -> None:
    # The app's config imports its signal handlers only inside a function: such imports count.
    assert imports.has_edge("telemetry.apps", "telemetry.map_events")
    assert imports.number_of_nodes() > 150

"""An admin edits a proposed change cell by cell before accepting it: the cells painted
occupied, free and unknown are saved through the API (bad cells answered with field
errors), the fleet's evidence no longer rewrites the edit, and accepting publishes it."""

from __future__ import annotations

from typing import Any

import numpy as np
import pytest
from django.contrib.auth.models import User

from maps import services, versions
from maps.domain.mapfile import MapMetadata, export_map, load_map_upload, map_yaml_text
from maps.domain.upkeep import Proposal
from maps.mapping.upkeep import store_proposal
from maps.models import Building, ChangeProposal, SubMap
from tests.conftest import client_for
from tests.support.upkeep import RES, STORED

CHANGES = "/api/buildings/boccioni_1/maps/Lab/changes/"
CABINET = [[50 + r, 60 + c] for r in range(3) for c in range(3)]  # free in STORED


@pytest.fixture
def lab(building: Building) -> SubMap:
    meta = MapMetadata("Lab.pgm", RES, (0.0, 0.0, 0.0), 0.65, 0.196, False)
    pgm, meta = export_map(STORED, meta, "Lab.pgm")
    loaded = load_map_upload(map_yaml_text(meta).encode(), {"Lab.pgm": pgm}, 10**7)
    return services.save_submap(building, "Lab", loaded)[0]


@pytest.fixture
def proposal(lab: SubMap) -> ChangeProposal:
    """The fleet proposes a 3 x 3 cabinet (seen on 2 passes) on version 1."""
    return ChangeProposal.objects.create(
        submap=lab, based_on=1, added=CABINET, added_passes=[2] * 9, passes=2, scans=100
    )


def edit(user: User, proposal: ChangeProposal, **cells: object) -> Any:
    return client_for(user).put(f"{CHANGES}{proposal.pk}/", cells, format="json")


def test_an_admin_paints_cells_and_the_accepted_version_has_them(
    proposal: ChangeProposal, admin: User, lab: SubMap
) -> None:
    kept = CABINET[:6]  # the admin drops the cabinet's last row ...
    wall = [[35, 35]]  # ... frees a cell of the stored cabinet ...
    fog = [[10, 10], [10, 11]]  # ... and makes two cells unknown
    answer = edit(admin, proposal, added=kept, removed=wall, unknown=fog)
    assert answer.status_code == 200, answer.json()
    shown = answer.json()
    assert shown["edited"] is True
    assert shown["added"] == kept
    assert shown["added_passes"] == [2] * 6
    assert shown["removed_passes"] == [0]
    assert client_for(admin).get(f"{CHANGES}{proposal.pk}/").json()["unknown"] == fog

    accepted = client_for(admin).post(f"{CHANGES}{proposal.pk}/accept", {}, format="json")
    assert accepted.status_code == 200
    version = versions.version_of(lab, accepted.json()["version"])
    assert "(edited)" in version.note
    grid = services.grid_of(version)
    assert all(grid[r, c] == 100 for r, c in kept)
    assert all(grid[r, c] == 0 for r, c in CABINET[6:])
    assert grid[35, 35] == 0
    assert grid[10, 10] == grid[10, 11] == -1
    before = services.grid_of(versions.version_of(lab, 1))
    assert int(np.count_nonzero(grid != before)) == 6 + 1 + 2


def test_bad_cells_are_answered_with_field_errors_and_nothing_changes(
    proposal: ChangeProposal, admin: User
) -> None:
    answer = edit(admin, proposal, added=[[0, 0], [500, 3]], removed=[[0, 0]], unknown=[[1]])
    assert answer.status_code == 400
    errors = answer.json()
    assert "unknown" in errors
    answer = edit(admin, proposal, added=[[0, 0], [500, 3]], removed=[[0, 0]])
    assert answer.status_code == 400
    errors = answer.json()
    assert "[500, 3] is outside the map" in str(errors["added"])
    assert "also in added" in str(errors["removed"])
    proposal.refresh_from_db()
    assert proposal.added == CABINET
    assert not proposal.edited


def test_the_fleet_no_longer_rewrites_an_edited_proposal(
    proposal: ChangeProposal, admin: User, lab: SubMap
) -> None:
    assert edit(admin, proposal, added=CABINET[:1]).status_code == 200
    seen = np.array([[70, 70]], np.intp)
    store_proposal(
        lab.pk, 1, Proposal(seen, seen[:0], np.array([3], np.uint16), np.zeros(0, np.uint16), 3), 9
    )
    proposal.refresh_from_db()
    assert proposal.added == CABINET[:1]


def test_a_decided_proposal_cannot_be_edited(proposal: ChangeProposal, admin: User) -> None:
    assert client_for(admin).post(f"{CHANGES}{proposal.pk}/reject").status_code == 200
    assert edit(admin, proposal, added=CABINET).status_code == 409


def test_only_admins_edit(proposal: ChangeProposal, operator: User, viewer: User) -> None:
    assert edit(operator, proposal, added=[]).status_code == 403
    assert client_for(viewer).get(f"{CHANGES}{proposal.pk}/").status_code == 200
    assert edit(viewer, proposal, added=[]).status_code == 403


def test_it_rejects_outsider(proposal: ChangeProposal, outsider: User) -> None:
    assert client_for(outsider).get(f"{CHANGES}{proposal.pk}/").status_code == 404
    assert edit(outsider, proposal, added=[]).status_code == 404


def test_robots_and_strangers_may_not_edit(proposal: ChangeProposal, token: str) -> None:
    url = f"{CHANGES}{proposal.pk}/"
    assert client_for(token).put(url, {"added": []}, format="json").status_code == 403
    assert client_for(None).put(url, {"added": []}, format="json").status_code == 401

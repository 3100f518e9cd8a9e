"""The tag range experiment (the paper's Tables 1 and 2) in its quick form."""

from __future__ import annotations

import pytest

from robots.agent.experiments import __main__ as experiments
from robots.agent.experiments import tag_range
from robots.agent.experiments.tag_range import RangeCase, RangeResult, max_range, padded_payload

QR_BYTES = {3: (33, 53), 4: (54, 78), 8: (155, 192)}  # over version v - 1, within v (level L)


@pytest.fixture(scope="module")
def quick_results() -> list[RangeResult]:
    return tag_range.run(*tag_range.QUICK)


@pytest.fixture
def quick(quick_results: list[RangeResult]) -> dict[RangeCase, float | None]:
    return {result.case: result.distance for result in quick_results}


@pytest.mark.slow
def test_the_marker_reads_farther_than_the_qr_code(quick: dict[RangeCase, float | None]) -> None:
    marker, qr = quick[RangeCase(0.06, 0.0, None)], quick[RangeCase(0.06, 0.0, 3)]
    assert qr is not None
    assert marker is not None
    assert 0.3 < qr < marker < 3.5


@pytest.mark.slow
def test_range_shrinks_with_the_view_angle(quick: dict[RangeCase, float | None]) -> None:
    for kind in (None, 3):
        head_on, slanted = quick[RangeCase(0.06, 0.0, kind)], quick[RangeCase(0.06, 60.0, kind)]
        assert head_on is not None
        assert slanted is not None
        assert slanted < head_on


@pytest.mark.slow
def test_a_bigger_marker_reads_from_farther() -> None:
    small = max_range(RangeCase(0.04, 0.0, None)).distance
    big = max_range(RangeCase(0.08, 0.0, None)).distance
    assert small is not None
    assert big is not None
    assert big > 1.5 * small


@pytest.mark.parametrize("version", [3, 4, 8])
def test_the_padded_payload_needs_exactly_its_qr_version(version: int) -> None:
    low, high = QR_BYTES[version]
    assert low < len(padded_payload(version)) <= high


@pytest.mark.slow
def test_the_command_prints_both_tables_beside_the_papers_figures(
    quick_results: list[RangeResult],
    capsys: pytest.CaptureFixture[str],
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    asked = []

    def run(*subset: object) -> list[RangeResult]:  # the quick run, already measured
        asked.append(subset)
        return quick_results

    monkeypatch.setattr(tag_range, "run", run)
    assert experiments.main(["tag-range", "--quick"]) == 0
    assert asked == [tag_range.QUICK]
    out = capsys.readouterr().out
    assert "Table 1" in out
    assert "Table 2" in out
    assert "(0.47)" in out  # the paper's QR v3 range for 6 cm
    assert "(0.90)" in out  # and its marker range at 60 degrees


def test_an_unknown_experiment_is_refused(capsys: pytest.CaptureFixture[str]) -> None:
    assert experiments.main(["no-such-thing"]) == 2
    assert "tag-range" in capsys.readouterr().err

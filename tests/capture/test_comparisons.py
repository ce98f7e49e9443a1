"""The comparisons log read back: rows as ``rigkit process`` writes them are read to the
digit, and a row that no run could have written (edited or damaged: a NaN laser range
counted as a success, an error that does not follow from its ranges) is skipped and
said, never counted."""

from __future__ import annotations

import math
from dataclasses import replace
from pathlib import Path

import pytest

from rigkit.capture.comparisons import (
    LOG_NAME,
    STATUS_NO_ESTIMATE,
    STATUS_NO_READING,
    append_rows,
    read_rows,
)
from tests.conftest import make_row


def test_rows_as_written_are_read_back(tmp_path: Path) -> None:
    rows = [make_row("T1", 301.234567, 0.731), make_row("T2", 499.9, -2.5),
            make_row("T3", 250.0, 0.0, status=STATUS_NO_ESTIMATE),
            make_row("T4", math.nan, 0.0, status=STATUS_NO_READING)]
    append_rows(tmp_path / LOG_NAME, rows)
    torn: list[str] = []
    back = read_rows(tmp_path / LOG_NAME, torn)
    assert torn == [] and [r.target for r in back] == ["T1", "T2", "T3", "T4"]
    assert back[0].error_pct == pytest.approx(rows[0].error_pct, rel=1e-8)


@pytest.mark.parametrize("change, why", [
    (dict(laser_range_m=math.nan), "laser_range_m nan is no range"),
    (dict(laser_range_m=-300.0), "laser_range_m -300 is no range"),
    (dict(estimate_range_m=math.inf), "estimate_range_m nan is no range"),  # written "nan"
    (dict(error_pct=-0.1), "do not follow from the ranges"),
    (dict(error_m=5.0), "do not follow from the ranges"),
    (dict(status="fine"), "status 'fine'"),
    (dict(valid_fraction=2.0), "not a fraction"),
    (dict(laser_readings=0), "0 laser readings for status ok"),
])
def test_a_row_no_run_writes_is_skipped_and_said(tmp_path: Path, change: dict, why: str) -> None:
    good = make_row("T1", 300.0, 0.5)
    append_rows(tmp_path / LOG_NAME, [replace(good, **change), make_row("T2", 300.0, 0.2)])
    torn: list[str] = []
    rows = read_rows(tmp_path / LOG_NAME, torn)
    assert [r.target for r in rows] == ["T2"]
    assert len(torn) == 1 and "line 2 is damaged" in torn[0] and why in torn[0]

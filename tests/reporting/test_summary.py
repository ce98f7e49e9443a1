"""The report summary: collecting session logs, statistics, text and CSV."""

from __future__ import annotations

import math
from pathlib import Path

import pytest

from rigkit.capture.comparisons import (
    LOG_NAME,
    STATUS_NO_ESTIMATE,
    STATUS_NO_READING,
    read_rows,
)
from rigkit.errors import InputError
from rigkit.reporting.summary import collect, format_text, summarize, write_csv
from tests.conftest import NEW_RUN, OLD_RUN
from tests.conftest import make_log as _session
from tests.conftest import make_row as _row

# --------------------------------------------------------------------------- collect


def test_collect_keeps_the_newest_run_unless_all_runs(two_runs: Path) -> None:
    newest = collect([two_runs])
    assert {r.run_id for r in newest} == {NEW_RUN} and len(newest) == 4
    everything = collect([two_runs], all_runs=True)
    assert [r.run_id for r in everything] == [OLD_RUN] * 2 + [NEW_RUN] * 4


def test_collect_reads_sessions_in_order_and_each_folder_once(tmp_path: Path) -> None:
    a = _session(tmp_path, "a", [_row("T1", 300.0, 0.1, session="a")])
    b = _session(tmp_path, "b", [_row("T1", 300.0, 0.2, session="b", run=OLD_RUN)])
    assert [r.session for r in collect([b, a, b])] == ["b", "a"]


def test_collect_errors_name_the_folder(tmp_path: Path) -> None:
    with pytest.raises(InputError, match="nope: no such session folder"):
        collect([tmp_path / "nope"])
    (tmp_path / "empty").mkdir()
    with pytest.raises(InputError, match=r"empty/comparisons.csv: no comparisons log"):
        collect([tmp_path / "empty"])
    (tmp_path / "file.txt").write_text("x")
    with pytest.raises(InputError, match="not a session folder"):
        collect([tmp_path / "file.txt"])
    bad = tmp_path / "bad"
    bad.mkdir()
    (bad / LOG_NAME).write_text("a,b\n1,2\n")
    with pytest.raises(InputError, match="not a comparisons log"):
        collect([bad])


# --------------------------------------------------------------------------- statistics


def test_summary_of_known_errors(two_runs: Path) -> None:
    s = summarize(collect([two_runs])).overall
    assert (s.total, s.ok, s.failed) == (4, 3, {STATUS_NO_ESTIMATE: 1})
    assert s.mean_abs_pct == pytest.approx(3.5 / 3)
    assert s.median_abs_pct == pytest.approx(1.0)
    assert s.max_abs_pct == pytest.approx(2.0)
    assert s.bias_pct == pytest.approx(-0.5 / 3)
    assert s.within_1 == pytest.approx(2 / 3)  # +1 % counts as within 1 %
    assert s.within_3 == 1.0 and s.outliers == 0


def test_buckets_by_laser_range() -> None:
    rows = [
        _row("a", 99.9, 0.2),
        _row("b", 100.0, 0.4),
        _row("c", 199.0, -0.6),
        _row("d", 450.0, 5.0),
        _row("e", 500.0, 0.1),
        _row("f", 260.0, 0.0, status=STATUS_NO_ESTIMATE),
        _row("g", math.nan, 0.0, status=STATUS_NO_READING),
    ]
    summary = summarize(rows)
    by_label = {b.label: b.stats for b in summary.buckets}
    assert list(by_label) == ["<100", "100-200", "200-300", "300-400", "400-500", ">=500"]
    assert [by_label[k].total for k in by_label] == [1, 2, 1, 0, 1, 1]
    assert by_label["100-200"].mean_abs_pct == pytest.approx(0.5)
    assert by_label["200-300"].ok == 0 and math.isnan(by_label["200-300"].mean_abs_pct)
    assert by_label["400-500"].outliers == 1 and by_label["400-500"].within_3 == 0.0
    # The row without a laser range is counted overall but is in no bucket.
    assert summary.overall.total == 7 and sum(b.stats.total for b in summary.buckets) == 6
    assert summary.overall.failed == {STATUS_NO_ESTIMATE: 1, STATUS_NO_READING: 1}


def test_bucket_edges_are_a_parameter() -> None:
    rows = [_row("a", 240.0, 0.1), _row("b", 260.0, 0.1)]
    labels = [b.label for b in summarize(rows, edges_m=(250,)).buckets]
    assert labels == ["<250", ">=250"]
    assert [b.stats.total for b in summarize(rows, edges_m=(250,)).buckets] == [1, 1]
    with pytest.raises(ValueError, match="increasing"):
        summarize(rows, edges_m=(300, 200))


def test_summary_of_nothing_usable() -> None:
    s = summarize([_row("a", 300.0, 0.0, status=STATUS_NO_ESTIMATE)]).overall
    assert (s.total, s.ok) == (1, 0)
    assert math.isnan(s.mean_abs_pct) and math.isnan(s.within_1)
    assert summarize([]).overall.total == 0


# --------------------------------------------------------------------------- text and CSV


def test_text_report_lists_rows_summary_and_buckets(two_runs: Path) -> None:
    rows = collect([two_runs]) + [_row("mast", 412.0, 5.0)]
    text = format_text(rows, summarize(rows))
    lines = text.splitlines()
    assert any(line.split()[:2] == ["field-1", "T2"] and "-2.000" in line for line in lines)
    assert any("mast" in line and "5.00 %: outside 1 %" in line for line in lines)
    assert any("T4" in line and "no estimate" in line for line in lines)
    assert "5 comparisons: 4 ok, 1 failed (no_estimate 1)" in text
    assert "400-500" in text and "300-400" in text and "<100" not in text  # empty: left out
    assert "run" not in lines[3].split()  # one run per session: no run column


def test_text_report_shows_the_run_when_a_session_has_several(two_runs: Path) -> None:
    rows = collect([two_runs], all_runs=True)
    text = format_text(rows, summarize(rows))
    assert "run" in text.splitlines()[3].split() and OLD_RUN in text


def test_csv_round_trips_through_read_rows(two_runs: Path, tmp_path: Path) -> None:
    rows = collect([two_runs])
    write_csv(tmp_path / "out.csv", rows)
    back = read_rows(tmp_path / "out.csv")
    assert [(r.target, r.status) for r in back] == [(r.target, r.status) for r in rows]
    assert back[0].error_pct == pytest.approx(rows[0].error_pct, rel=1e-5)

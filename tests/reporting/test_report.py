"""rigkit report: collecting session logs, statistics, text/CSV, plots and the command."""

from __future__ import annotations

import math
from pathlib import Path

import cv2
import numpy as np
import pytest

from rigkit import cli
from rigkit.capture.comparisons import (
    LOG_NAME,
    STATUS_NO_ESTIMATE,
    STATUS_NO_READING,
    STATUS_OK,
    Comparison,
    append_rows,
    read_rows,
)
from rigkit.errors import InputError
from rigkit.report import (
    INK,
    OUTLIER,
    PALETTE,
    collect,
    format_text,
    nice_ticks,
    plot_error_vs_range,
    plot_estimate_vs_laser,
    summarize,
    tick_label,
    write_csv,
)

OLD_RUN, NEW_RUN = "20261122T090000Z", "20261123T100000Z"


def _row(
    target: str,
    laser: float,
    error_pct: float,
    *,
    session: str = "field-1",
    run: str = NEW_RUN,
    status: str = STATUS_OK,
    sigma: float = 0.5,
) -> Comparison:
    ok = status == STATUS_OK
    estimate = laser * (1 + error_pct / 100) if ok else math.nan
    return Comparison(
        run_id=run,
        time_utc="2026-11-23T10:00:00Z",
        session=session,
        target=target,
        u=1000.0,
        v=800.0,
        window_px=31,
        laser_range_m=laser,
        laser_readings=3 if math.isfinite(laser) else 0,
        laser_spread_m=0.05,
        estimate_range_m=estimate,
        estimate_sigma_m=sigma if ok else math.nan,
        valid_fraction=0.95 if ok else 0.0,
        error_m=estimate - laser,
        error_pct=100 * (estimate - laser) / laser,
        status=status,
    )


def _session(root: Path, name: str, *runs: list[Comparison]) -> Path:
    """A session folder whose log gets one append per run, as `rigkit process` does."""
    folder = root / name
    folder.mkdir(parents=True, exist_ok=True)
    for rows in runs:
        append_rows(folder / LOG_NAME, rows)
    return folder


@pytest.fixture
def two_runs(tmp_path: Path) -> Path:
    old = [_row(t, 300.0, 2.0, run=OLD_RUN) for t in ("T1", "T2")]
    new = [
        _row("T1", 250.0, 1.0),
        _row("T2", 350.0, -2.0),
        _row("T3", 450.0, 0.5),
        _row("T4", 420.0, 0.0, status=STATUS_NO_ESTIMATE),
    ]
    return _session(tmp_path, "field-1", old, new)


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
    assert any("mast" in line and "ok (>3 %)" in line for line in lines)
    assert any("T4" in line and STATUS_NO_ESTIMATE in line for line in lines)
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


# --------------------------------------------------------------------------- ticks


@pytest.mark.parametrize(
    "lo, hi, expected",
    [
        (151.0, 549.0, [100.0, 200.0, 300.0, 400.0, 500.0, 600.0]),
        (0.0, 1.0, [0.0, 0.2, 0.4, 0.6, 0.8, 1.0]),
        (-4.6, 4.6, [-6.0, -4.0, -2.0, 0.0, 2.0, 4.0, 6.0]),
    ],
)
def test_nice_ticks_use_1_2_5_steps(lo: float, hi: float, expected: list[float]) -> None:
    a, b, ticks = nice_ticks(lo, hi)
    assert ticks == pytest.approx(expected) and (a, b) == (ticks[0], ticks[-1])


def test_nice_ticks_never_collapse() -> None:
    a, b, ticks = nice_ticks(300.0, 300.0)
    assert a < 300.0 < b and len(ticks) >= 3
    assert nice_ticks(math.nan, 1.0)[:2] == (0.0, 1.0)


def test_tick_labels() -> None:
    assert tick_label(300.0, [200.0, 300.0]) == "300"
    assert tick_label(0.4, [0.2, 0.4]) == "0.4"
    assert tick_label(2.0, [0.0, 2.0], signed=True) == "+2"
    assert tick_label(-1e-17, [-0.5, 0.0, 0.5], signed=True) == "0.0"


# --------------------------------------------------------------------------- plots


def _blobs(img: np.ndarray, colour: tuple[int, int, int]) -> list[tuple[float, float]]:
    """Centroids (x, y) of solid patches of exactly ``colour`` (marker interiors)."""
    mask = np.all(img == np.array(colour, np.uint8), axis=2).astype(np.uint8)
    n, _, stats, centroids = cv2.connectedComponentsWithStats(mask)
    return [tuple(centroids[i]) for i in range(1, n) if stats[i, cv2.CC_STAT_AREA] >= 15]


def _points(img: np.ndarray) -> list[tuple[float, float]]:
    """Marker centroids of the first session, without its legend swatch (the topmost)."""
    blobs = sorted(_blobs(img, PALETTE[0]), key=lambda c: c[1])
    return sorted(blobs[1:])  # left to right


PLOT_ROWS = [
    _row("near", 200.0, -2.0),
    _row("far", 400.0, 2.0),
    _row("gone", 300.0, 0.0, status=STATUS_NO_ESTIMATE),
]


def test_estimate_vs_laser_puts_points_on_the_diagonal() -> None:
    img = plot_estimate_vs_laser(PLOT_ROWS)
    assert img.shape == (700, 1000, 3) and img.dtype == np.uint8
    (x1, y1), (x2, y2) = _points(img)  # the no_estimate row is not drawn
    assert x2 - x1 > 200 and y1 - y2 > 150  # the far point is right of and above the near one
    assert not np.any(np.all(img == OUTLIER, axis=2))  # no outlier, no red ring


def test_error_vs_range_puts_points_either_side_of_zero() -> None:
    img = plot_error_vs_range(PLOT_ROWS)
    assert img.shape == (700, 1000, 3)
    (x1, y1), (x2, y2) = _points(img)
    assert x2 - x1 > 200 and y1 - y2 > 100  # -2 % below, +2 % above
    zero = round((y1 + y2) / 2)  # the zero line, half-way between +2 % and -2 %
    band = img[zero - 2 : zero + 3, round(x1) + 20 : round(x2) - 20]
    assert np.all(band == INK, axis=2).any(axis=0).mean() > 0.9


def test_outliers_are_ringed_and_plot_size_is_a_parameter() -> None:
    rows = [*PLOT_ROWS, _row("mast", 350.0, 5.0)]
    for plot in (plot_estimate_vs_laser, plot_error_vs_range):
        img = plot(rows, size=(800, 600))
        assert img.shape == (600, 800, 3)
        assert np.all(img == OUTLIER, axis=2).sum() > 30


@pytest.mark.parametrize(
    "rows",
    [
        [],
        [_row("a", 300.0, 0.0, status=STATUS_NO_ESTIMATE)],
        [_row("a", 302.0, 0.4)],
        [_row("a", 300.0, 0.4), _row("b", 300.0, -0.6), _row("c", 300.0, -2.0)],
        [_row("a", 250.0, 0.4), _row("b", 400.0, 80.0), _row("c", math.nan, 0, status="x")],
    ],
    ids=["none", "no-usable", "single", "same-range", "off-scale"],
)
def test_plots_handle_edge_cases(rows: list[Comparison]) -> None:
    for plot in (plot_estimate_vs_laser, plot_error_vs_range):
        img = plot(rows)
        assert img.shape == (700, 1000, 3)
        assert (img < 128).any(axis=2).sum() > 500  # text and axes drawn
    usable = [r for r in rows if r.ok]
    assert len(_blobs(plot_error_vs_range(rows), PALETTE[0])) == (len(usable) + 1 if usable else 0)


# --------------------------------------------------------------------------- command


@pytest.fixture
def main(monkeypatch: pytest.MonkeyPatch):
    """cli.main with the report command registered (whether or not cli lists it yet)."""
    if "report" not in cli.COMMANDS:
        monkeypatch.setattr(cli, "COMMANDS", (*cli.COMMANDS, "report"))
    return cli.main


OUTPUTS = ("comparisons.csv", "report.txt", "estimate_vs_laser.png", "error_vs_range.png")


def test_report_command_writes_all_outputs(main, two_runs: Path, tmp_path: Path, capsys) -> None:
    other = _session(tmp_path, "field-2", [_row("T1", 510.0, 0.3, session="field-2")])
    out = tmp_path / "out" / "report"
    assert main(["report", str(two_runs), str(other), "--out", str(out)]) == 0
    stdout = capsys.readouterr().out
    assert sorted(p.name for p in out.iterdir()) == sorted(OUTPUTS)  # no temporary left
    report = (out / "report.txt").read_text()
    assert stdout.startswith(report) and "wrote " in stdout.splitlines()[-1]
    assert len(read_rows(out / "comparisons.csv")) == 5
    for name in OUTPUTS[2:]:
        img = cv2.imread(str(out / name))
        assert img is not None and img.shape == (700, 1000, 3)


def test_report_command_all_runs(main, two_runs: Path, tmp_path: Path) -> None:
    out = tmp_path / "out"
    assert main(["report", str(two_runs), "--out", str(out), "--all-runs"]) == 0
    assert len(read_rows(out / "comparisons.csv")) == 6


@pytest.mark.parametrize(
    "args, message",
    [
        (lambda s, t: [str(t / "missing")], "missing: no such session folder"),
        (lambda s, t: [], "no session folders given"),
        (lambda s, t: [str(s), "--out", str(s)], "is a session folder"),
    ],
    ids=["missing-session", "no-session", "out-is-session"],
)
def test_report_command_errors_are_one_line(
    main, two_runs: Path, tmp_path: Path, capsys, args, message
) -> None:
    argv = ["report", *args(two_runs, tmp_path)]
    if "--out" not in argv:
        argv += ["--out", str(tmp_path / "out")]
    log_before = (two_runs / LOG_NAME).read_bytes()
    assert main(argv) == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith("rigkit report: error: ") and message in err
    assert len(err.splitlines()) == 1
    assert not (tmp_path / "out").exists()
    assert (two_runs / LOG_NAME).read_bytes() == log_before

"""Summaries, tables and plots of the rangefinder-vs-estimate logs of capture sessions.

:func:`collect` reads the ``comparisons.csv`` log of each session folder (by default only
each session's newest run), :func:`summarize` computes error statistics overall and per
laser-range bucket, :func:`format_text` and :func:`write_csv` give the table (the plots are
:mod:`rigkit.reporting.plots`).

Sign convention (as in :mod:`rigkit.capture.comparisons`): ``error = estimate - laser``; a
positive error puts the target too far. Percentages are of the laser range. Statistics
use the usable (``ok``) rows only; the others are counted by status.
"""

from __future__ import annotations

import math
import statistics
from collections import Counter
from collections.abc import Collection, Iterable, Sequence
from dataclasses import dataclass
from pathlib import Path

from rigkit.capture.comparisons import (
    LOG_NAME,
    STATUS_OK,
    Comparison,
    csv_text,
    read_rows,
)
from rigkit.capture.results import RESULTS_DIR
from rigkit.core.files import write_text
from rigkit.core.tables import render_table
from rigkit.errors import InputError
from rigkit.reporting.scale import current_rows
from rigkit.reporting.verdict import CALIBRATED_LABEL, row_label

#: Bucket edges by laser range, metres: <100, 100-200, ..., 400-500, >=500.
DEFAULT_EDGES_M: tuple[float, ...] = (100.0, 200.0, 300.0, 400.0, 500.0)
#: The two tolerance bands of the report, percent of the laser range.
TIGHT_PCT = 1.0
LOOSE_PCT = 3.0
_EPS_PCT = 1e-9  # a value logged as exactly 1 % counts as within 1 %


# --------------------------------------------------------------------------- reading


def collect(session_dirs: Iterable[Path], all_runs: bool = False,
            torn: list[str] | None = None) -> list[Comparison]:
    """The comparison rows of the given session folders, in the order given.

    Each folder must hold ``comparisons.csv`` at its top level. By default only each
    session's current run is kept, the one in its ``results/``
    (:func:`rigkit.reporting.scale.current_rows`: not the log's greatest run id, which a
    clock set back makes an old run's); ``all_runs`` keeps every run. A folder given twice is
    read once. InputError (naming the folder or file) for a missing folder, a folder
    without a log, or a file that is no log; damaged rows are skipped and said in
    ``torn`` (:func:`rigkit.capture.comparisons.read_rows`).
    """
    rows: list[Comparison] = []
    seen: set[Path] = set()
    for folder in session_dirs:
        folder = Path(folder)
        key = folder.resolve()
        if key in seen:
            continue
        seen.add(key)
        rows.extend(_session_rows(folder, all_runs, torn))
    return rows


def _session_rows(folder: Path, all_runs: bool, torn: list[str] | None
                  ) -> list[Comparison]:
    if not folder.exists():
        raise InputError(f"{folder}: no such session folder")
    if not folder.is_dir():
        raise InputError(f"{folder}: not a session folder (give the folder that holds {LOG_NAME})")
    if not all_runs and (folder / RESULTS_DIR / LOG_NAME).is_file():
        return current_rows(folder, torn)  # the run results/ holds, whatever the log's ids
    rows = read_rows(folder / LOG_NAME, torn)
    return rows if all_runs else current_rows(folder, torn)


# --------------------------------------------------------------------------- statistics


@dataclass(frozen=True)
class Stats:
    """Error statistics of a group of comparisons.

    ``total`` counts every row, ``ok`` the usable ones (status ``ok`` with a finite
    error), ``failed`` the others by status. The error figures are over the ok rows, in
    percent of the laser range (NaN when there are none); ``within_1`` / ``within_3`` are
    the shares (0-1) of ok rows with ``|error| <= 1 %`` / ``<= 3 %``; ``outliers`` counts
    ok rows beyond 3 %.
    """

    total: int
    ok: int
    failed: dict[str, int]
    mean_abs_pct: float
    median_abs_pct: float
    max_abs_pct: float
    bias_pct: float
    within_1: float
    within_3: float
    outliers: int


@dataclass(frozen=True)
class Bucket:
    """The rows whose laser range is in ``[lo_m, hi_m)`` (either end may be infinite)."""

    lo_m: float
    hi_m: float
    stats: Stats

    @property
    def label(self) -> str:
        if math.isinf(self.lo_m):
            return f"<{self.hi_m:g}"
        if math.isinf(self.hi_m):
            return f">={self.lo_m:g}"
        return f"{self.lo_m:g}-{self.hi_m:g}"


@dataclass(frozen=True)
class Summary:
    """Statistics of all rows and per laser-range bucket (rows without a laser range are
    in ``overall`` but in no bucket; empty buckets are kept, with ``total == 0``)."""

    overall: Stats
    buckets: tuple[Bucket, ...]


def is_outlier(row: Comparison, limit_pct: float = LOOSE_PCT) -> bool:
    """A usable row whose error is beyond ``limit_pct`` percent."""
    return row.ok and abs(row.error_pct) > limit_pct + _EPS_PCT


def stats(rows: Sequence[Comparison]) -> Stats:
    """Counts and error statistics of ``rows`` (see :class:`Stats`)."""
    errors = [row.error_pct for row in rows if row.ok]
    failed = Counter(_failure(row) for row in rows if not row.ok)
    nan = math.nan
    abs_errors = [abs(e) for e in errors]
    return Stats(
        total=len(rows),
        ok=len(errors),
        failed=dict(sorted(failed.items())),
        mean_abs_pct=statistics.fmean(abs_errors) if errors else nan,
        median_abs_pct=statistics.median(abs_errors) if errors else nan,
        max_abs_pct=max(abs_errors) if errors else nan,
        bias_pct=statistics.fmean(errors) if errors else nan,
        within_1=_share(abs_errors, TIGHT_PCT),
        within_3=_share(abs_errors, LOOSE_PCT),
        outliers=sum(1 for e in abs_errors if e > LOOSE_PCT + _EPS_PCT),
    )


def _failure(row: Comparison) -> str:
    # Status "ok" without a finite error should not happen; keep it visible if it does.
    return row.status if row.status != STATUS_OK else "ok_without_error"


def _share(abs_errors: Sequence[float], limit_pct: float) -> float:
    if not abs_errors:
        return math.nan
    return sum(1 for e in abs_errors if e <= limit_pct + _EPS_PCT) / len(abs_errors)


def summarize(rows: Sequence[Comparison], edges_m: Sequence[float] = DEFAULT_EDGES_M) -> Summary:
    """Statistics of ``rows`` overall and per bucket of laser range.

    ``edges_m`` (increasing, metres) split the range axis into ``len(edges_m) + 1``
    buckets ``[-inf, e0), [e0, e1), ..., [e_last, inf)``.
    """
    edges = [float(e) for e in edges_m]
    if any(b <= a for a, b in zip(edges, edges[1:], strict=False)) or not all(
        math.isfinite(e) for e in edges
    ):
        raise ValueError(f"bucket edges must be finite and increasing, got {list(edges_m)}")
    bounds = [-math.inf, *edges, math.inf]
    buckets = tuple(
        Bucket(lo, hi, stats([r for r in rows if lo <= r.laser_range_m < hi]))
        for lo, hi in zip(bounds, bounds[1:], strict=False)
    )
    return Summary(overall=stats(rows), buckets=buckets)


# --------------------------------------------------------------------------- text and CSV


def _num(value: float, spec: str) -> str:
    return "-" if not math.isfinite(value) else format(value, spec)


def _share_text(share: float, n: int) -> str:
    if not math.isfinite(share):
        return "-"
    return f"{round(share * n)}/{n}"


def _several_runs(rows: Sequence[Comparison]) -> bool:
    runs: dict[str, set[str]] = {}
    for row in rows:
        runs.setdefault(row.session, set()).add(row.run_id)
    return any(len(ids) > 1 for ids in runs.values())


def format_rows(rows: Sequence[Comparison], calibrated: Collection[tuple[str, str]] = ()
                ) -> str:
    """One line per comparison; a run column appears when a session has several runs;
    the rows whose (session, target) ``calibrated`` the rig say so."""
    with_run = _several_runs(rows)
    header = ["session", *(["run"] if with_run else []), "target"]
    left = len(header)
    header += ["laser m", "estimate m", "error m", "error %", "sigma m", "status"]
    lines = []
    for r in rows:
        status = row_label(r, TIGHT_PCT)
        if (r.session, r.target) in calibrated:
            status += f" ({CALIBRATED_LABEL})"
        lines.append(
            [
                r.session,
                *([r.run_id] if with_run else []),
                r.target,
                _num(r.laser_range_m, ".2f"),
                _num(r.estimate_range_m, ".2f"),
                _num(r.error_m, "+.2f"),
                _num(r.error_pct, "+.3f"),
                _num(r.estimate_sigma_m, ".2f"),
                status,
            ]
        )
    if not lines:
        return "no comparisons"
    return render_table(header, lines, left=[*range(left), len(header) - 1])


def _failed_text(s: Stats) -> str:
    if not s.failed:
        return "0 failed"
    parts = ", ".join(f"{k} {v}" for k, v in s.failed.items())
    return f"{s.total - s.ok} failed ({parts})"


def format_stats(s: Stats) -> str:
    """The overall statistics as a few indented lines."""
    lines = [f"{s.total} comparisons: {s.ok} ok, {_failed_text(s)}"]
    if s.ok:
        lines += [
            f"  |error|: mean {s.mean_abs_pct:.3f} %, median {s.median_abs_pct:.3f} %, "
            f"max {s.max_abs_pct:.3f} %",
            f"  bias (mean signed error, estimate - laser): {s.bias_pct:+.3f} %",
            f"  within {TIGHT_PCT:g} %: {_share_text(s.within_1, s.ok)} "
            f"({100 * s.within_1:.1f} %), within {LOOSE_PCT:g} %: "
            f"{_share_text(s.within_3, s.ok)} ({100 * s.within_3:.1f} %)",
            f"  outliers beyond {LOOSE_PCT:g} %: {s.outliers}",
        ]
    return "\n".join(lines)


def format_buckets(buckets: Sequence[Bucket]) -> str:
    """One line per non-empty bucket."""
    header = ["laser range m", "n", "ok", "mean|e| %", "median|e| %", "max|e| %", "bias %"]
    header += [f"<={TIGHT_PCT:g} %", f"<={LOOSE_PCT:g} %"]
    lines = []
    for b in buckets:
        s = b.stats
        if s.total == 0:
            continue
        lines.append(
            [
                b.label,
                str(s.total),
                str(s.ok),
                _num(s.mean_abs_pct, ".3f"),
                _num(s.median_abs_pct, ".3f"),
                _num(s.max_abs_pct, ".3f"),
                _num(s.bias_pct, "+.3f"),
                _share_text(s.within_1, s.ok),
                _share_text(s.within_3, s.ok),
            ]
        )
    if not lines:
        return "no comparisons with a laser range"
    return render_table(header, lines, left=[0])


def _outlier_lines(rows: Sequence[Comparison]) -> list[str]:
    """The usable rows beyond 3 %, worst first, as one indented line each."""
    worst = sorted((r for r in rows if is_outlier(r)), key=lambda r: -abs(r.error_pct))
    return [
        f"    {r.session}/{r.target}: {r.error_pct:+.3f} % ({r.error_m:+.2f} m at "
        f"{r.laser_range_m:.2f} m)"
        for r in worst
    ]


def format_text(rows: Sequence[Comparison], summary: Summary,
                calibrated: Collection[tuple[str, str]] = ()) -> str:
    """The full text report: every comparison, the summary, and the per-bucket table;
    ``calibrated``: the (session, target) rows that calibrated their rig, marked and left
    out of ``summary`` by the caller (they cannot check the scale they made)."""
    sessions = list(dict.fromkeys(r.session for r in rows))
    used = [f"{r.session}/{r.target}" for r in rows if (r.session, r.target) in calibrated]
    parts = [
        f"rangefinder comparisons: {len(rows)} rows from {len(sessions)} session(s)"
        + (f" ({', '.join(sessions)})" if sessions else ""),
        "error = estimate - laser (positive: estimate too far); % of the laser range",
        "",
        format_rows(rows, calibrated),
        *([f"calibrated the rig, so not counted below (they cannot check it): "
           f"{', '.join(used)}"] if used else []),
        "",
        "summary",
        format_stats(summary.overall),
        *_outlier_lines(rows),
        "",
        "by laser range",
        format_buckets(summary.buckets),
    ]
    return "\n".join(parts) + "\n"


def write_csv(path: Path, rows: Sequence[Comparison]) -> None:
    """The rows as CSV with the log's columns (readable again by ``read_rows``)."""
    write_text(path, csv_text(rows))

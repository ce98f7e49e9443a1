"""The rangefinder-vs-estimate log: one CSV row per target per processing run.

Each session keeps ``comparisons.csv`` at its top level. ``rigkit process`` appends one
row per target each time it runs, tagged with the run's id, and never rewrites earlier
rows, so the file is the session's history of comparisons. Readers usually want the
newest run only (:func:`latest_run`).

Sign convention: ``error_m = estimate_range_m - laser_range_m`` (positive: the depth map
puts the target too far), ``error_pct = 100 * error_m / laser_range_m``. Ranges are
along the laser's line of sight from its aperture, in metres.
"""

from __future__ import annotations

import csv
import io
import math
from collections.abc import Iterable, Sequence
from dataclasses import asdict, dataclass, fields
from pathlib import Path

from rigkit.capture.session import MAX_SIDE_PX, is_plain_name
from rigkit.core.files import append_whole
from rigkit.core.safefs import read_regular
from rigkit.errors import InputError
from rigkit.rangefinder.framing import MIN_RANGE_M
from rigkit.rig.profile import MAX_RANGE_M

LOG_NAME = "comparisons.csv"

#: ``status`` values: a usable comparison, or why there is none.
STATUS_OK = "ok"
STATUS_NO_ESTIMATE = "no_estimate"  # no finite depth in the target's window
STATUS_NO_READING = "no_reading"  # the target has no laser reading


@dataclass(frozen=True)
class Comparison:
    """One target of one run.

    Units: metres, pixels, percent; ``NaN`` where a value does not exist (e.g. no
    estimate). ``u``, ``v``: target centre in the original left image, px (x right, y
    down). ``window_px``: side of the square window the estimate is taken over.
    ``laser_range_m``: median of the target's readings (slope distance from the laser's
    aperture); ``laser_spread_m``: their standard deviation (0 for one reading).
    ``estimate_range_m``: median depth in the window converted to range along the line of
    sight from the laser aperture; ``estimate_sigma_m``: its one-sigma uncertainty (the
    pipeline's per-pixel sigma at the median, scaled the same way). ``valid_fraction``:
    share of window pixels with an estimate.
    """

    run_id: str
    time_utc: str
    session: str
    target: str
    u: float
    v: float
    window_px: int
    laser_range_m: float
    laser_readings: int
    laser_spread_m: float
    estimate_range_m: float
    estimate_sigma_m: float
    valid_fraction: float
    error_m: float
    error_pct: float
    status: str

    @property
    def ok(self) -> bool:
        return self.status == STATUS_OK and math.isfinite(self.error_pct)


COLUMNS: tuple[str, ...] = tuple(f.name for f in fields(Comparison))
_TYPES = {f.name: f.type for f in fields(Comparison)}


SIGNIFICANT_DIGITS = 9
"""Significant digits a float keeps in the log (micrometres at 1 km)."""


def format_row(row: Comparison) -> dict[str, str]:
    """The row as CSV strings: floats to :data:`SIGNIFICANT_DIGITS` significant digits."""
    out: dict[str, str] = {}
    for key, value in asdict(row).items():
        if isinstance(value, float):
            out[key] = "nan" if not math.isfinite(value) else f"{value:.{SIGNIFICANT_DIGITS}g}"
        else:
            out[key] = str(value)
    return out


def csv_text(rows: Sequence[Comparison], header: bool = True) -> str:
    """The rows as CSV text with the log's columns (readable by :func:`read_rows`)."""
    buffer = io.StringIO()
    writer = csv.DictWriter(buffer, fieldnames=COLUMNS, lineterminator="\n")
    if header:
        writer.writeheader()
    for row in rows:
        writer.writerow(format_row(row))
    return buffer.getvalue()


def append_rows(path: Path, rows: Sequence[Comparison]) -> None:
    """Append rows to the log at ``path``, writing the header if the file is new.

    The rows land whole or not at all (:func:`rigkit.core.files.append_whole`: a full
    disk leaves the log as it was). OSError if they cannot be written.
    """
    append_whole(path, csv_text(rows, header=not path.exists() or path.stat().st_size == 0))


LOG_LIMIT = 64 << 20
"""The largest comparisons log read, bytes: some 250,000 rows (a thousand targets
processed 250 times); a larger file is refused unread."""


def read_rows(path: Path, torn: list[str] | None = None) -> list[Comparison]:
    """Every row of a comparisons log; InputError naming the file when it is no log
    or larger than :data:`LOG_LIMIT`.

    A row that does not parse or holds what no run writes (what a crash or a full disk
    mid-append leaves, in rigkit before append_whole; a value edited in: a NaN, a range
    of 1e200 m) is skipped and said in ``torn`` ("line 7: ...") when a list is given,
    so one damaged row does not make the whole history unreadable (a report, ``session
    show``). Without ``torn`` such a row is refused, InputError naming the file and
    line: what fits a rig must not rest on a row it cannot trust."""
    try:
        text = read_regular(path, LOG_LIMIT, "a comparisons log").decode("utf-8")
    except FileNotFoundError:
        raise InputError(f"{path}: no comparisons log (run `rigkit process` first)") from None
    except (OSError, UnicodeDecodeError) as exc:
        raise InputError(f"{path}: cannot read the comparisons log ({exc})") from None
    if text and not text.endswith("\n") and "\n" in text:
        # A last line without its newline was cut short, even if what is left parses.
        text = text[: text.rindex("\n") + 1]
        if torn is not None:
            torn.append(f"{path}: the last line was cut short and was skipped")
    reader = csv.DictReader(io.StringIO(text))
    try:
        fieldnames = reader.fieldnames
    except csv.Error as exc:
        raise InputError(f"{path}: not a comparisons log (its first line: {exc})") from None
    if fieldnames is None:
        return []
    missing = [c for c in COLUMNS if c not in fieldnames]
    if missing:
        raise InputError(f"{path}: not a comparisons log (missing columns {', '.join(missing)})")
    rows = []
    while True:
        try:  # the reader goes on at the next line after a line it cannot split
            record = next(reader)
            rows.append(_parse(record))
        except StopIteration:
            return rows
        except (csv.Error, TypeError, ValueError, OverflowError) as exc:
            if torn is None:
                raise InputError(f"{path}: line {reader.line_num} is no comparison rigkit "
                                 f"wrote ({exc}); remove the line or process the session "
                                 "again") from None
            torn.append(f"{path}: line {reader.line_num} is damaged and was skipped ({exc})")


def _parse(record: dict[str, str]) -> Comparison:
    values: dict[str, object] = {}
    for name in COLUMNS:
        text = record[name]
        if text is None:
            raise ValueError(f"column {name} is empty")
        kind = _TYPES[name]
        values[name] = float(text) if kind == "float" else int(text) if kind == "int" else text
    row = Comparison(**values)  # type: ignore[arg-type]
    _check_row(row)
    return row


_STATUSES = (STATUS_OK, STATUS_NO_ESTIMATE, STATUS_NO_READING)
MAX_READINGS = 1_000_000
"""The most laser readings one target's row may count."""


def _check_row(row: Comparison) -> None:
    """ValueError where the row is no comparison ``rigkit process`` writes: a status of
    its own, ranges that are positive where they exist, and the errors that follow from
    them (to the log's digits). An edited or damaged row is skipped as damaged, not
    counted: a NaN laser range must not count as "within 1 %", nor a stored error stand
    for ranges that do not give it."""
    if row.status not in _STATUSES:
        raise ValueError(f"status {row.status!r} is none of {', '.join(_STATUSES)}")
    if not (is_plain_name(row.session) and is_plain_name(row.target)):
        raise ValueError("the session or target is no name rigkit gives (a plain name)")
    if not (row.run_id.isprintable() and row.time_utc.isprintable()):
        raise ValueError("the run id or time holds characters that are not printable")
    if not (abs(row.u) <= MAX_SIDE_PX and abs(row.v) <= MAX_SIDE_PX
            and 1 <= row.window_px <= MAX_SIDE_PX):
        raise ValueError("the target's pixel or window is not a position")
    if not 0.0 <= row.valid_fraction <= 1.0:
        raise ValueError(f"valid_fraction {row.valid_fraction:g} is not a fraction")
    laser, estimate = row.laser_range_m, row.estimate_range_m
    if (row.laser_readings > 0) != (row.status != STATUS_NO_READING) or not \
            0 <= row.laser_readings <= MAX_READINGS:
        raise ValueError(f"{row.laser_readings} laser readings for status {row.status}")
    if row.status != STATUS_NO_READING:
        _check_range("laser_range_m", laser)
        if not 0 <= row.laser_spread_m <= MAX_RANGE_M:
            raise ValueError(f"laser_spread_m {row.laser_spread_m:g} is not a spread of ranges")
    if row.status != STATUS_OK:
        return
    _check_range("estimate_range_m", estimate)
    if not 0 <= row.estimate_sigma_m <= MAX_RANGE_M:
        raise ValueError(f"estimate_sigma_m {row.estimate_sigma_m:g} is not an uncertainty "
                         "of a range")
    digits = 10.0 ** -(SIGNIFICANT_DIGITS - 1)  # what the log's rounding may move
    if (not math.isclose(row.error_m, estimate - laser, rel_tol=0.0,
                         abs_tol=digits * (estimate + laser))
            or not math.isclose(row.error_pct, 100 * row.error_m / laser,
                                rel_tol=10 * digits, abs_tol=1e-12)):
        raise ValueError(f"error_m {row.error_m:g} and error_pct {row.error_pct:g} do not "
                         f"follow from the ranges ({estimate:g} m against {laser:g} m)")


def _check_range(name: str, value: float) -> None:
    """ValueError unless ``value`` is a range rigkit measures or compares: from the
    rangefinder's shortest to the longest any rig profile allows (NaN, infinity,
    1e200 m are not)."""
    if not MIN_RANGE_M <= value <= MAX_RANGE_M:
        raise ValueError(f"{name} {value:g} is no range ({MIN_RANGE_M:g} to "
                         f"{MAX_RANGE_M:g} m)")


def latest_run(rows: Iterable[Comparison]) -> list[Comparison]:
    """The rows of each session's newest run (run ids sort by time)."""
    rows = list(rows)
    newest: dict[str, str] = {}
    for row in rows:
        if row.run_id > newest.get(row.session, ""):
            newest[row.session] = row.run_id
    return [row for row in rows if row.run_id == newest[row.session]]

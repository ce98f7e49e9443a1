"""The field verdict from known comparison rows."""

from __future__ import annotations

import json
import math
from pathlib import Path

from rigkit.capture import RESULTS_DIR
from rigkit.capture.comparisons import STATUS_NO_ESTIMATE, STATUS_NO_READING
from rigkit.reporting.verdict import judge, offset_note, tolerance_pct
from rigkit.rig import load_rig
from tests.conftest import make_row

ROOT = Path(__file__).resolve().parents[2]
SYNTHETIC = load_rig(ROOT / "rigs" / "synthetic.yaml")  # 4608 px, exact: 2 sigma < 1 % at 300 m
P1000 = load_rig(ROOT / "rigs" / "p1000-tripod.yaml")  # f known to 1 %: 2 sigma > 3 %


def test_tolerance_is_one_percent_or_the_rigs_two_sigma() -> None:
    assert tolerance_pct(SYNTHETIC, 300.0) == 1.0
    assert tolerance_pct(P1000, 300.0) > 3.0
    assert tolerance_pct(P1000, math.nan) == 1.0
    # Bursts shrink the offset's share of the budget, and so the tolerance.
    assert tolerance_pct(P1000, 500.0, frames=5) < tolerance_pct(P1000, 500.0)


def test_all_targets_within_one_percent_is_done() -> None:
    rows = [make_row(f"T{i}", 300.0, error) for i, error in enumerate((0.5, -0.9, 1.0), 1)]
    verdict = judge(rows, SYNTHETIC)
    assert verdict.ok and verdict.headline == "3/3 targets within 1 %: done"
    assert verdict.advice == ()


def test_failures_say_what_to_capture_again() -> None:
    rows = [
        make_row("T1", 300.0, 0.2),
        make_row("T2", 300.0, 2.5),
        make_row("T3", 300.0, 0.0, status=STATUS_NO_ESTIMATE),
        make_row("T4", math.nan, 0.0, status=STATUS_NO_READING),
    ]
    verdict = judge(rows, SYNTHETIC)
    assert not verdict.ok
    assert verdict.headline == "1/4 targets within 1 %: capture again"
    assert [t.ok for t in verdict.targets] == [True, False, False, False]
    assert "T2: off by +2.5 %" in verdict.advice
    assert any("without a reading" in a for a in verdict.advice)
    assert any("textured ground" in a for a in verdict.advice)


def test_a_common_bias_points_at_the_baselines() -> None:
    rows = [make_row("T1", 300.0, 2.0), make_row("T2", 310.0, 2.4)]
    advice = judge(rows, SYNTHETIC).advice
    assert any("C_lr and C_lb" in a for a in advice)
    mixed = judge([make_row("T1", 300.0, 2.0), make_row("T2", 310.0, -2.4)], SYNTHETIC).advice
    assert not any("C_lr and C_lb" in a for a in mixed)


def test_a_loose_rig_states_its_tolerance() -> None:
    verdict = judge([make_row("T1", 300.0, 2.0)], P1000)
    assert verdict.ok and verdict.headline.startswith("1/1 targets within tolerance (up to 3.")


def test_no_targets_is_not_done() -> None:
    verdict = judge([], SYNTHETIC)
    assert not verdict.ok and "no laser targets" in verdict.headline


def test_offset_note_from_the_latest_run(tmp_path: Path) -> None:
    assert offset_note(tmp_path) is None  # not processed yet
    results = tmp_path / RESULTS_DIR
    results.mkdir()
    for fraction, note in ((0.0012, None), (0.0042, "+-0.42 % of depth"), (None, None)):
        (results / "depth.json").write_text(json.dumps({"offset_depth_error_fraction": fraction}))
        got = offset_note(tmp_path)
        assert got is None if note is None else note in str(got)
    (results / "depth.json").write_text("{not json")
    assert offset_note(tmp_path) is None

"""The field verdict from known comparison rows: one goal, the rig's 2σ at the estimate,
the same words everywhere."""

from __future__ import annotations

import math
from dataclasses import replace
from pathlib import Path

from rigkit.capture.comparisons import STATUS_NO_ESTIMATE, STATUS_NO_READING
from rigkit.reporting.verdict import judge, row_label, run_verdict, two_sigma_pct
from rigkit.rig import load_rig
from tests.conftest import make_record, make_row

ROOT = Path(__file__).resolve().parents[2]
SYNTHETIC = load_rig(ROOT / "rigs" / "synthetic.yaml")  # 4608 px, exact: 2 sigma < 1 % at 300 m
P1000 = load_rig(ROOT / "rigs" / "p1000-tripod.yaml")  # f known to 1 %: 2 sigma > 3 %


def test_two_sigma_is_the_rigs_budget() -> None:
    assert two_sigma_pct(SYNTHETIC, 300.0) < 1.0
    assert two_sigma_pct(P1000, 300.0) > 3.0
    assert math.isnan(two_sigma_pct(P1000, math.nan))
    # Bursts shrink the offset's share of the budget, and so the 2 sigma.
    assert two_sigma_pct(P1000, 500.0, frames=5) < two_sigma_pct(P1000, 500.0)


def test_all_targets_within_one_percent_is_done() -> None:
    rows = [make_row(f"T{i}", 300.0, error) for i, error in enumerate((0.5, -0.9, 1.0), 1)]
    verdict = judge(rows, SYNTHETIC)
    assert verdict.ok and verdict.headline == "3/3 targets within 1 %: done"
    assert verdict.advice == ()
    assert [t.label for t in verdict.targets] == ["within 1 %"] * 3


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
    assert any(a.startswith("T2: 2.50 %: outside 1 %, outside the 2σ of ±0.") for a in
               verdict.advice)
    assert "T3: no estimate" in verdict.advice and "T4: no reading" in verdict.advice
    assert any("without a reading" in a for a in verdict.advice)
    assert any("textured ground" in a for a in verdict.advice)


def test_a_common_bias_points_at_the_baselines() -> None:
    rows = [make_row("T1", 300.0, 2.0), make_row("T2", 310.0, 2.4)]
    advice = judge(rows, SYNTHETIC).advice
    assert any("C_lr and C_lb" in a for a in advice)
    mixed = judge([make_row("T1", 300.0, 2.0), make_row("T2", 310.0, -2.4)], SYNTHETIC).advice
    assert not any("C_lr and C_lb" in a for a in mixed)


def test_a_loose_rig_misses_the_goal_and_says_its_two_sigma() -> None:
    # Before: the tolerance grew to the rig's 2 sigma and "2 %" passed as "ok".
    (target,) = judge([make_row("T1", 300.0, 1.43)], P1000).targets
    assert not target.ok
    assert target.label.startswith("1.43 %: outside 1 %, inside the 2σ of ±3.")


def test_a_wild_reading_cannot_widen_its_own_tolerance() -> None:
    # A typed 3000000 for 300.0: the 2σ is the rig's at the estimate (300 m), not at the
    # reading, so the target is far outside it (it was "4/4 within (up to 13492.4 %)").
    row = make_row("T4", 300.0, 0.0)
    row = replace(row, laser_range_m=3_000_000.0, error_pct=-99.99)
    (target,) = judge([row], SYNTHETIC).targets
    assert not target.ok and "outside the 2σ of ±0." in target.label


def test_a_shortfall_keeps_the_verdict_from_done() -> None:
    # Before: "done" beside "the offset alone leaves +-2.68 % of depth".
    rows = [make_row("T1", 300.0, 0.2)]
    note = "the disparity offset alone leaves +-2.68 % of depth (1 sigma) at the median range"
    verdict = judge(rows, SYNTHETIC, shortfalls=[note])
    assert not verdict.ok and "done" not in verdict.headline
    assert verdict.headline.startswith("1/1 targets within 1 %: capture again")


def test_row_labels_are_the_verdicts_words_without_the_rig() -> None:
    assert row_label(make_row("T1", 300.0, -0.4)) == "within 1 %"
    assert row_label(make_row("T1", 300.0, 1.43)) == "1.43 %: outside 1 %"
    assert row_label(make_row("T1", 300.0, 0.0, status=STATUS_NO_ESTIMATE)) == "no estimate"


def test_no_targets_is_not_done() -> None:
    verdict = judge([], SYNTHETIC)
    assert not verdict.ok and "no laser targets" in verdict.headline


def test_a_runs_verdict_carries_what_its_record_says(tmp_path: Path) -> None:
    """The verdict on a run from its record: the frames it stacked (the offset's share
    of the 2σ shrinks with them), what it said falls short (no "done" then)."""
    from rigkit.capture.actions import create_session

    session = create_session(tmp_path / "ridge", ROOT / "rigs" / "p1000-tripod.yaml")
    rows = [make_row("T1", 300.0, 0.2), make_row("T2", 320.0, -0.3)]
    done = run_verdict(session, rows, P1000, make_record())
    assert done.ok and done.shortfalls == ()
    short = run_verdict(session, rows, P1000, make_record(shortfalls=("the offset ...",)))
    assert not short.ok and short.shortfalls == ("the offset ...",)
    assert "the run says it misses the goal" in short.headline
    far = [make_row("T1", 500.0, 5.0)]
    burst = run_verdict(session, far, P1000, make_record(burst_length=5)).targets[0]
    assert burst.two_sigma_pct == two_sigma_pct(P1000, far[0].estimate_range_m, frames=5)


# ------------------------------------------------------------ targets that calibrated the rig


def test_targets_that_calibrated_the_rig_are_shown_and_not_counted() -> None:
    """After calibrating from a session, its own targets cannot prove the scale they
    made (on 81dfff3: "4/6 within 1 %", counted as proof)."""
    rows = [make_row(f"T{i}", 300.0, error) for i, error in enumerate((0.2, 0.3, 1.4), 1)]
    verdict = judge(rows, SYNTHETIC, calibrated={"T1", "T2"})
    assert verdict.headline == ("0/1 independent targets within 1 % (2 more calibrated the "
                                "rig: not counted): capture again")
    assert [t.calibrated for t in verdict.targets] == [True, True, False]
    assert verdict.targets[0].label == "within 1 % (calibrated the rig: not a check)"
    assert verdict.advice[0].startswith("T3: 1.40 %")
    alone = judge(rows[:2], SYNTHETIC, calibrated={"T1", "T2"})
    assert not alone.ok and alone.headline.startswith("no independent target: all 2")


def _calibrated_session(tmp_path: Path):
    """A session (two targets) whose rig's provenance names its frames and its T1."""
    from rigkit.capture.actions import create_session
    from rigkit.capture.model import LaserReading
    from rigkit.capture.targets import add_target
    from rigkit.reporting.scale import frames_fingerprint
    from rigkit.rig.provenance import Calibration, CalibrationSource

    path = tmp_path / "ridge"
    session = create_session(path, ROOT / "rigs" / "p1000-tripod.yaml")
    for name, pixel in (("T1", (300.0, 260.0)), ("T2", (100.0, 320.0))):
        session = add_target(session, name, pixel,
                             readings=[LaserReading(300.0, "2026-04-12T08:01:12Z", "manual")])
    source = CalibrationSource("ridge", str(path), frames_fingerprint(session), "run-1",
                               "2026:04:12 08:00:00", {"T1": (300.0, 260.0), "T2": (1.0, 1.0)})
    record = Calibration("2026-04-13T09:00:00Z", "p1000-tripod", (source,), 300.0)
    return session, replace(session.rig(), calibration=record)


def test_a_runs_verdict_marks_its_calibration_targets_and_says_the_source(
        tmp_path: Path) -> None:
    from rigkit.reporting.scale import calibration_targets, scale_source

    session, profile = _calibrated_session(tmp_path)
    # T2 moved since (another pixel): the calibration's T2 was another target.
    assert calibration_targets(profile, session) == {"T1"}
    rows = [make_row("T1", 300.0, 0.1), make_row("T2", 300.0, 0.4)]
    verdict = run_verdict(session, rows, profile, make_record(session))
    assert [t.calibrated for t in verdict.targets] == [True, False]
    assert verdict.source == scale_source(profile) == (
        "laser-calibrated 2026-04-13 from ridge (2 targets, taken 2026:04:12 08:00:00): "
        "C_lb 2.000 +- 0.020 m")
    assert "taped (C_lb 2.000 +- 0.020 m, not laser-calibrated)" == scale_source(session.rig())

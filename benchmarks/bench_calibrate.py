"""The rig calibrated by its own laser (`rigkit rig calibrate`), on rendered sessions
whose profile is wrong: depth bias against ground truth before and after.

    python -m benchmarks.bench_calibrate --seeds 301-320 --width 2304 --work out/bench-calibrate
    python -m benchmarks.bench_calibrate --seeds 321-326 --stray 10   # one reading 10 % off
    python -m benchmarks.bench_calibrate --mistakes --seeds 501-524 --width 2304

Each seed renders a scene at the paper's protocol (--width px across 6 deg, 300 m) as a
session with laser targets whose readings carry --laser-sigma-m of noise, and gives it a
profile whose C_lb and focal length are off while it claims the usual tolerances (1 % on
f, 2 cm on each baseline). It then processes the session, calibrates the rig from it,
sets the written profile and processes again, as a user would:

    rigkit process S; rigkit rig calibrate S --out S.yaml; rigkit session set-rig S
    --rig S.yaml; rigkit process S

By default every seed has --targets targets, C_lb off by +-1.5 % and f by +-5 % (signs
drawn per seed). With --mistakes each seed draws what a field team gets wrong: C_lb taped
0.5-3 % off and f 5 % off (signs drawn), 3-12 targets, 0-2 of them lasered on something
nearer (5-90 % short). Where the calibration refuses because the tape (or the lens spec)
is beyond its tolerance, the user gives --beyond-tolerance, as the refusal says.

Printed per seed: the mistakes, the median depth bias against the ground truth before
and after, the fitted C_lb against the true 2 m in units of its written sigma, whether
f * C_lr was fitted, the targets left out (or the refusal) and the outcome against the
issue's bar: the fit either refuses naming every bad target, or gives |bias| <= 0.3 %
with the truth inside its stated 2 sigma (C_lb, and f*C_lr where fitted).
"""

from __future__ import annotations

import argparse
import math
import sys
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np
import yaml

from benchmarks.common import OUT, RIGS, seed_list
from rigkit.batch import new_run_id, process_session
from rigkit.capture.positioning import set_rig
from rigkit.errors import InputError
from rigkit.reporting.calibration_report import calibration_record
from rigkit.reporting.scale import read_sessions
from rigkit.rig import load_rig
from rigkit.rig.adjustment import LaserTarget
from rigkit.rig.calibrated import calibrated_profile
from rigkit.rig.calibration import fit_scale
from rigkit.rig.profile import dump_rig
from rigkit.synth import SynthParams, generate_scene
from rigkit.synth.evaluate import evaluate_scene
from rigkit.synth.session import write_synthetic_session

TRUE_C_LB_M = 2.0
BAR_PCT = 0.3


@dataclass(frozen=True)
class Mistakes:
    """What a seed's field team got wrong: C_lb and f off (fractions), the targets, and
    the gross readings (target index -> the fraction of the truth the laser read)."""

    lb_off: float
    f_off: float
    targets: int
    gross: dict[int, float]


@dataclass(frozen=True)
class Outcome:
    seed: int
    mistakes: Mistakes
    before: float
    after: float
    z: float
    shape: str
    left_out: str
    verdict: str
    passed: bool


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--seeds", default="301-320")
    parser.add_argument("--work", type=Path, default=OUT / "bench-calibrate")
    parser.add_argument("--width", type=int, default=1152)
    parser.add_argument("--targets", type=int, default=6)
    parser.add_argument("--laser-sigma-m", type=float, default=0.3)
    parser.add_argument("--lb-off", type=float, default=1.5,
                        help="how far the profile's C_lb is off, %% (sign drawn per seed)")
    parser.add_argument("--f-off", type=float, default=5.0,
                        help="how far the profile's focal length is off, %% (sign drawn)")
    parser.add_argument("--stray", type=float, default=0.0,
                        help="put the first target's reading this many %% off")
    parser.add_argument("--mistakes", action="store_true",
                        help="draw per seed a field team's mistakes (module docstring)")
    parser.add_argument("--plan", action="store_true",
                        help="print what N targets over a depth spread buy (the fit's own "
                             "sigma, no rendering) and stop")
    args = parser.parse_args(argv)
    if args.plan:
        _plan(args.laser_sigma_m)
        return 0
    print(f"{'seed':>5} {'C_lb off':>8} {'f off':>6} {'tgts':>4} {'gross':>14} "
          f"{'bias before':>11} {'after':>7} {'z':>5} {'shape':>5} {'left out':>14}  outcome")
    outcomes = []
    for seed in seed_list(args.seeds):
        outcome = _seed(seed, args)
        outcomes.append(outcome)
        _print(outcome)
    _summary(outcomes)
    return 0


def _mistakes(seed: int, args: argparse.Namespace) -> Mistakes:
    rng = np.random.default_rng(seed)
    sign = lambda: float(rng.choice([-1, 1]))  # noqa: E731
    if not args.mistakes:
        gross = {0: 1 + args.stray / 100} if args.stray else {}
        return Mistakes(sign() * args.lb_off / 100, sign() * args.f_off / 100, args.targets,
                        gross)
    lb_off = sign() * float(rng.uniform(0.5, 3.0)) / 100
    f_off = sign() * args.f_off / 100
    targets = int(rng.integers(3, 13))
    count = int(rng.integers(0, 3))
    picked = rng.choice(targets, size=min(count, targets), replace=False)
    gross = {int(i): float(1 - rng.uniform(0.05, 0.90)) for i in picked}
    return Mistakes(lb_off, f_off, targets, gross)


def _seed(seed: int, args: argparse.Namespace) -> Outcome:
    mistakes = _mistakes(seed, args)
    folder = args.work / f"seed-{seed}"
    if not (folder / "session.yaml").is_file():
        scene = generate_scene(SynthParams(width=args.width, height=args.width * 3 // 4), seed)
        write_synthetic_session(scene, folder, n_targets=mistakes.targets,
                                laser_sigma_m=args.laser_sigma_m, seed=seed)
        _gross(folder, mistakes.gross)
    set_rig(folder, _wrong_profile(folder, mistakes.lb_off, mistakes.f_off))
    before = _processed_bias(folder, seed)
    bad = {f"T{i + 1}" for i in mistakes.gross}
    gross = ",".join(f"T{i + 1}:{100 * (1 - f):.0f}%" for i, f in sorted(mistakes.gross.items()))
    try:
        given = read_sessions([folder])
        try:
            fit = fit_scale(given.targets, given.profile)
            overruled = ""
        except InputError as exc:
            if "--beyond-tolerance" not in str(exc) or "put " not in str(exc):
                raise
            fit = fit_scale(given.targets, given.profile, overrule=True)  # as it says
            overruled = " (tape overruled)"
    except InputError as exc:
        named = {name for name in bad if f"/{name}" in str(exc) or f"{name} " in str(exc)}
        ok = named == bad and bool(bad)
        missed = ",".join(sorted(bad - named)) or "none: no bad target"
        verdict = f"refused, naming {'every bad target' if ok else 'not ' + missed}"
        print(f"        {exc}", flush=True)
        return Outcome(seed, mistakes, before, math.nan, math.nan, "-", gross or "-",
                       verdict, ok)
    written = calibrated_profile(given.profile, fit, calibration_record(fit, given))
    path = folder.parent / f"seed-{seed}-calibrated.yaml"
    path.write_text(dump_rig(written.profile))
    set_rig(folder, path)
    after = _processed_bias(folder, seed)
    c_lb = written.profile.baseline_lb
    z = (c_lb.value_m - TRUE_C_LB_M) / c_lb.tolerance_m
    left = {r.target.name.rsplit("/", 1)[-1] for r in fit.rejected}
    covered = abs(z) <= 2 and _shape_covered(fit, mistakes.f_off)
    ok = abs(after) <= BAR_PCT and covered
    verdict = (f"{'pass' if ok else 'FAIL'}: |bias| {'<=' if abs(after) <= BAR_PCT else '>'} "
               f"{BAR_PCT} %, truth {'inside' if covered else 'OUTSIDE'} 2 sigma{overruled}")
    if left != bad:
        verdict += (f"; left out {','.join(sorted(left)) or 'none'} of bad "
                    f"{','.join(sorted(bad)) or 'none'}")
    return Outcome(seed, mistakes, before, after, z, "fit" if fit.shape_fitted else "held",
                   ",".join(sorted(left)) or "-", verdict, ok)


def _shape_covered(fit, f_off: float) -> bool:
    """Where f*C_lr was fitted, whether the true product lies within 2 sigma of it (the
    profile's f is (1 + f_off) times the truth, so the truth is a = 1 / (1 + f_off))."""
    if not fit.shape_fitted:
        return True
    return abs(fit.shape - 1 / (1 + f_off)) <= 2 * fit.shape_sigma


def _print(o: Outcome) -> None:
    m = o.mistakes
    gross = ",".join(f"T{i + 1}:{100 * (1 - f):.0f}%" for i, f in sorted(m.gross.items())) or "-"
    print(f"{o.seed:>5} {100 * m.lb_off:+7.2f}% {100 * m.f_off:+5.0f}% {m.targets:>4} "
          f"{gross:>14} {o.before:+10.3f}% {o.after:+6.3f}% {o.z:+5.1f} {o.shape:>5} "
          f"{o.left_out:>14}  {o.verdict}", flush=True)


def _summary(outcomes: list[Outcome]) -> None:
    n = len(outcomes)
    passed = sum(o.passed for o in outcomes)
    fitted = [o for o in outcomes if math.isfinite(o.after)]
    refused = [o for o in outcomes if not math.isfinite(o.after)]
    before = np.median(np.abs([o.before for o in outcomes]))
    print(f"\n{n} seeds: {passed}/{n} meet the bar ({100 * passed / n:.0f} %; the issue asks "
          f">= 90 %); |bias| before {before:.2f} % median")
    if fitted:
        after = np.abs([o.after for o in fitted])
        z = np.array([o.z for o in fitted])
        print(f"  {len(fitted)} written: |bias| after median {np.median(after):.3f} %, max "
              f"{np.max(after):.3f} %, within {BAR_PCT} % in {np.sum(after <= BAR_PCT)}/"
              f"{len(fitted)}; C_lb within 2 sigma in {np.sum(np.abs(z) <= 2)}/{len(fitted)} "
              f"(RMS z {np.sqrt(np.mean(z**2)):.2f})")
    if refused:
        named = sum(o.passed for o in refused)
        print(f"  {len(refused)} refused: naming every bad target in {named}/{len(refused)}")


def _plan(laser_sigma_m: float, own: float = 0.002, z0: float = 300.0) -> None:
    """The one-sigma the fit leaves, for N targets spread evenly over +-spread of z0, each
    with the laser's sigma and an estimate good to ``own`` (0.2 %), under the P1000
    profile's tolerances (the laser's constant a priori 0 +- one reading's sigma)."""
    profile = load_rig(RIGS / "p1000-tripod.yaml")
    print(f"laser +-{laser_sigma_m:g} m, estimate +-{100 * own:g} %, at {z0:g} m; "
          "one sigma of the depth maps' scale and of f*C_lr, %")
    print(f"{'targets':>8} {'spread':>8} {'scale':>7} {'f*C_lr':>8}")
    for n in (1, 3, 6, 12):
        for spread in (0.03, 0.15, 0.4):
            ranges = np.linspace(z0 * (1 - spread), z0 * (1 + spread), n) if n > 1 else [z0]
            targets = [LaserTarget(f"T{i}", t, laser_sigma_m, t, own * t, z0,
                                   pixel=(100.0 * i, 0.0), window_px=9)
                       for i, t in enumerate(ranges)]
            fit = fit_scale(targets, profile)
            shape = f"{100 * fit.shape_sigma:7.2f}" if fit.shape_fitted else "   held"
            print(f"{n:>8} {'+-' + f'{100 * spread:g} %':>8} {100 * fit.map_scale_sigma:7.3f}"
                  f" {shape:>8}")


def _wrong_profile(folder: Path, lb_off: float, f_off: float) -> Path:
    """The scene's true profile (the rig.yaml it was rendered with) with C_lb and f off,
    and usual tolerances."""
    true = load_rig(folder / "rig.yaml")
    cameras = {role: replace(cam, focal_px=cam.focal_px * (1 + f_off),
                             focal_given=("px", cam.focal_px * (1 + f_off)),
                             focal_tolerance=0.01)
               for role, cam in true.cameras.items()}
    wrong = replace(true, name=f"{true.name}-taped", cameras=cameras,
                    baseline_lr=replace(true.baseline_lr, tolerance_m=0.02),
                    baseline_lb=replace(true.baseline_lb, value_m=TRUE_C_LB_M * (1 + lb_off),
                                        tolerance_m=0.02))
    path = folder.parent / f"{folder.name}-wrong.yaml"
    path.write_text(dump_rig(wrong))
    return path


def _gross(folder: Path, gross: dict[int, float]) -> None:
    """Targets lasered on something nearer: their reading ``fraction`` of the truth."""
    if not gross:
        return
    data = yaml.safe_load((folder / "session.yaml").read_text())
    for index, fraction in gross.items():
        if index >= len(data["targets"]):
            continue
        reading = data["targets"][index]["readings"][0]
        reading["slope_distance_m"] = round(reading["slope_distance_m"] * fraction, 3)
    (folder / "session.yaml").write_text(yaml.safe_dump(data))


def _processed_bias(folder: Path, seed: int) -> float:
    outcome = process_session(folder, new_run_id())
    if not outcome.ok:
        raise SystemExit(f"seed {seed}: {outcome.message}")
    metrics = evaluate_scene(folder, folder / "results" / "depth.npy")
    return 100 * metrics.median_bias if math.isfinite(metrics.median_bias) else math.nan


if __name__ == "__main__":
    sys.exit(main())

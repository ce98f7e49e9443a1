"""Depth accuracy against ground truth, with the paper's metric (Table 1).

A left pixel is judged when it has ground-truth depth, a surface with texture (not a
plain wall or an empty backdrop: ``ground_truth/flat_left.npy``, where no method can
match and rigkit gives no depth on purpose) and the right camera sees the same surface
point (inside the right image and not occluded there, from the ground truth poses and
the right view's own depth). A judged pixel without an estimate (NaN) counts as a
miss: it is in the denominator but under no threshold. *False depth* is the share of
the pixels with nothing to match (no surface, or a flat one) that got a depth.

Where the world moves between the captures (a scene with movers or cloud shadows has
``ground_truth/moved_left.npy``, :mod:`rigkit.synth.changes`), :class:`ChangeMetrics`
splits the score: the static pixels (judged, neither moved nor under a changing cloud
shadow) are scored as above; of the moved pixels (every left pixel with ground truth
that a mover covers in any view, judged or not: the right view may not see that
surface at all) it counts those given any depth and those given a depth more than
``MOVED_WRONG`` off the left view's truth; the judged pixels only a cloud shadow
changes are scored on their own. The static pixels are also scored away from what has
nothing to match: *textured* static pixels are those whose matching window holds no
pixel without texture (no surface or a flat one; the pipeline's texture window, half of
it either side: ``TEXTURE_MARGIN_PX``). A thin textured strip between plain walls, or
the ground's edge under a blank sky, looks plain to any window that matches it, and
may stay empty (issue 35's bar for the town scenes is set on these pixels).
"""

from __future__ import annotations

import csv
import io
import math
from collections.abc import Iterable, Sequence
from dataclasses import asdict, dataclass, fields, replace
from pathlib import Path

import cv2
import numpy as np

from rigkit.capture.results import RunFiles, session_comparisons
from rigkit.core.files import read_npy
from rigkit.core.outputs import write_outputs
from rigkit.core.tables import render_table
from rigkit.errors import InputError
from rigkit.pipeline.settings import PipelineSettings
from rigkit.synth.io import SceneTruth, load_scene

THRESHOLDS = (0.005, 0.01, 0.02, 0.03)
OCCLUSION_TOLERANCE = 0.002  # relative depth difference that still counts as the same surface
MOVED_WRONG = 0.03  # a moved pixel's depth this far off (relative) counts as wrong
TEXTURE_MARGIN_PX = round(PipelineSettings().texture_window_px
                          / PipelineSettings().stereo_scale / 2)
"""Half the pipeline's texture window, in image px (9 stereo px at half resolution:
9 px): a textured pixel this close to one with nothing to match is not scored as
textured (module docstring)."""


@dataclass(frozen=True)
class ChangeMetrics:
    """Scores split by what changed between the captures. Fractions in [0, 1], bias a
    signed fraction; NaN where a group has no pixel."""

    static_share: float  # judged pixels neither moved nor shadow-changed / judged pixels
    static_under_1: float  # static pixels under 1 % error (a missing estimate is a miss)
    static_bias: float  # median (estimate - truth) / truth over static pixels with an estimate
    moved_share: float  # moved pixels / left pixels with ground truth
    moved_density: float  # moved pixels given any depth / moved pixels
    moved_wrong: float  # moved pixels given a depth off by more than MOVED_WRONG / moved pixels
    shadow_share: float  # judged pixels only a cloud shadow changes / judged pixels
    shadow_under_1: float  # of those, under 1 % error
    textured_share: float = math.nan  # static pixels TEXTURE_MARGIN_PX clear of plain / static
    textured_under_1: float = math.nan  # of those, under 1 % error


@dataclass(frozen=True)
class Metrics:
    """Scores of one depth map. Fractions in [0, 1]; bias is a signed fraction."""

    scene: str
    judged_pixels: int
    density: float  # judged pixels with a finite estimate
    under_0_5: float
    under_1: float
    under_2: float
    under_3: float
    median_bias: float  # median of (estimate - truth) / truth over estimated pixels
    failed: bool = False
    reason: str = ""
    # Pixels with nothing to match (sky, empty background, a flat surface) that
    # received a depth, as a fraction of those pixels; NaN when the scene has none.
    false_depth: float = math.nan
    changes: ChangeMetrics | None = None  # scenes where the world moves (module docstring)


def visible_in_right(truth: SceneTruth) -> np.ndarray:
    """(H, W) bool: left pixels whose surface point the right camera also sees."""
    left, right = truth.cameras["left"], truth.cameras["right"]
    z = truth.depth("left").astype(np.float64)
    v, u = np.mgrid[0 : left.height, 0 : left.width].astype(np.float64)
    X = left.rays(u, v) * z[..., None] + left.C
    uv, zr = right.project(X)
    ui, vi = np.rint(uv[..., 0]), np.rint(uv[..., 1])
    inside = (ui >= 0) & (ui < right.width) & (vi >= 0) & (vi < right.height) & np.isfinite(zr)
    zr_seen = np.full(z.shape, np.nan)
    depth_r = truth.depth("right")
    zr_seen[inside] = depth_r[vi[inside].astype(int), ui[inside].astype(int)]
    with np.errstate(invalid="ignore"):
        same = np.abs(zr_seen - zr) <= OCCLUSION_TOLERANCE * zr
    return inside & same & np.isfinite(z)


def offset_error_px(truth: SceneTruth, depth: np.ndarray, focal_px: float) -> float:
    """The disparity offset error of a depth map: the median over judged pixels of
    ``f C_lr (1/z_est - 1/z_true)`` (px, > 0: disparities too large, depths too
    short). depth: (H, W) metres, NaN = none; ``focal_px``: the f it was made with."""
    judged = visible_in_right(truth) & np.isfinite(depth)
    z_true = truth.depth("left")[judged].astype(np.float64)
    fc = focal_px * truth.baseline_lr_m
    return float(np.median(fc / depth[judged] - fc / z_true))


def depth_metrics(
    estimate: np.ndarray, truth: np.ndarray, judged: np.ndarray, scene: str = "",
    flat: np.ndarray | None = None,
) -> Metrics:
    """Score ``estimate`` against ``truth`` over the ``judged`` mask.

    estimate, truth: (H, W) float, metres, z in the left camera (NaN = none);
    judged: (H, W) bool; flat: (H, W) bool, surfaces with no texture (None: none),
    counted with the no-surface pixels for false depth.
    """
    if estimate.shape != truth.shape:
        raise InputError(
            f"{scene or 'estimate'}: depth map is {estimate.shape[1]}x{estimate.shape[0]}, "
            f"ground truth is {truth.shape[1]}x{truth.shape[0]}"
        )
    n = int(judged.sum())
    if n == 0:
        raise InputError(f"{scene or 'scene'}: no pixel to judge (no overlap with the right view)")
    est = estimate[judged].astype(np.float64)
    gt = truth[judged].astype(np.float64)
    has = np.isfinite(est)
    rel = np.abs(est[has] - gt[has]) / gt[has]
    fractions = [float(np.count_nonzero(rel < t)) / n for t in THRESHOLDS]
    bias = float(np.median((est[has] - gt[has]) / gt[has])) if has.any() else math.nan
    no_surface = ~np.isfinite(truth) if flat is None else ~np.isfinite(truth) | flat
    false_depth = (
        float(np.isfinite(estimate[no_surface]).mean()) if no_surface.any() else math.nan
    )
    return Metrics(
        scene=scene,
        judged_pixels=n,
        density=float(has.mean()),
        under_0_5=fractions[0],
        under_1=fractions[1],
        under_2=fractions[2],
        under_3=fractions[3],
        median_bias=bias,
        false_depth=false_depth,
    )


def _relative_errors(estimate: np.ndarray, truth: np.ndarray, where: np.ndarray) -> np.ndarray:
    """(N,) float64: (estimate - truth) / truth at the ``where`` pixels, NaN = no estimate."""
    gt = truth[where].astype(np.float64)
    return (estimate[where].astype(np.float64) - gt) / gt


def _share(part: np.ndarray, whole: np.ndarray) -> float:
    """count(part) / count(whole), NaN when ``whole`` is empty."""
    n = int(np.count_nonzero(whole))
    return float(np.count_nonzero(part)) / n if n else math.nan


def change_metrics(
    estimate: np.ndarray,
    truth: np.ndarray,
    judged: np.ndarray,
    moved: np.ndarray,
    shadow: np.ndarray,
    plain: np.ndarray | None = None,
) -> ChangeMetrics:
    """Score ``estimate`` separately on static, moved and shadow-changed pixels, and on
    the static pixels clear of ``plain`` ones (module docstring).

    estimate, truth: (H, W) float, metres, z in the left camera (NaN = none); judged,
    moved, shadow: (H, W) bool (:func:`visible_in_right`, ground_truth/moved_left.npy and
    shadow_changed_left.npy); plain: (H, W) bool, nothing to match there (no surface or
    a flat one; None: where ``truth`` is NaN)."""
    static = judged & ~moved & ~shadow
    textured = static & ~_near(~np.isfinite(truth) if plain is None else plain,
                               TEXTURE_MARGIN_PX)
    rel_textured = _relative_errors(estimate, truth, textured)
    shadowed = judged & ~moved & shadow
    rel = _relative_errors(estimate, truth, static)
    has = np.isfinite(rel)
    rel_shadow = _relative_errors(estimate, truth, shadowed)
    moved = moved & np.isfinite(truth)
    rel_moved = _relative_errors(estimate, truth, moved)
    return ChangeMetrics(
        static_share=_share(static, judged),
        static_under_1=_share(np.abs(rel[has]) < 0.01, static),
        static_bias=float(np.median(rel[has])) if has.any() else math.nan,
        moved_share=_share(moved, np.isfinite(truth)),
        moved_density=_share(np.isfinite(rel_moved), moved),
        moved_wrong=_share(np.abs(rel_moved[np.isfinite(rel_moved)]) > MOVED_WRONG, moved),
        shadow_share=_share(shadowed, judged),
        shadow_under_1=_share(np.abs(rel_shadow[np.isfinite(rel_shadow)]) < 0.01, shadowed),
        textured_share=_share(textured, static),
        textured_under_1=_share(np.abs(rel_textured[np.isfinite(rel_textured)]) < 0.01,
                                textured),
    )


def _near(mask: np.ndarray, margin_px: int) -> np.ndarray:
    """(H, W) bool: within ``margin_px`` of a ``mask`` pixel along both axes (a square
    window centred there holds one)."""
    kernel = np.ones((2 * margin_px + 1,) * 2, np.uint8)
    return cv2.dilate(mask.astype(np.uint8), kernel).astype(bool)


def failed_metrics(scene: str, reason: str) -> Metrics:
    nan = math.nan
    return Metrics(scene, 0, 0.0, nan, nan, nan, nan, nan, failed=True, reason=reason)


def estimate_candidates(depth_dir: Path | None, scene_dir: Path) -> list[Path]:
    """Where a scene's estimate may be: ``DEPTH_DIR/<scene>.npy``,
    ``DEPTH_DIR/<scene>-depth.npy`` (as ``rigkit depth --help`` writes it) or
    ``DEPTH_DIR/<scene>/depth.npy``; without ``depth_dir``, the scene's own
    ``results/depth.npy`` (a processed synthetic session)."""
    if depth_dir is None:
        return [RunFiles.of_session(scene_dir).depth]
    name = scene_dir.name
    return [depth_dir / f"{name}.npy", depth_dir / f"{name}-depth.npy",
            depth_dir / name / "depth.npy"]


def find_estimate(depth_dir: Path | None, scene_dir: Path) -> Path | None:
    """The first of :func:`estimate_candidates` that exists."""
    return next((c for c in estimate_candidates(depth_dir, scene_dir) if c.is_file()), None)


def evaluate_scene(scene_dir: Path, estimate_path: Path | None,
                   looked: Sequence[Path] = ()) -> Metrics:
    """Metrics of the estimate at ``estimate_path`` (None: a failure saying it was not
    found in any of ``looked``)."""
    name = scene_dir.name
    truth = load_scene(scene_dir)
    if estimate_path is None:
        where = f" (looked for {', '.join(map(str, looked))})" if looked else ""
        return failed_metrics(name, f"no depth estimate{where}")
    try:  # its header first: a map of another size is not read (depth_metrics says so)
        est = read_npy(estimate_path)
    except (OSError, InputError) as exc:
        return failed_metrics(name, f"unreadable estimate: {exc}")
    if est.ndim != 2 or not np.issubdtype(est.dtype, np.floating):
        return failed_metrics(name, f"unreadable estimate {estimate_path}: not an (H, W) "
                              f"map of real depths ({est.dtype}, {est.ndim} axes)")
    depth = truth.depth("left")
    if est.shape == depth.shape and not np.any(np.isfinite(est) & (est > 0)):
        return failed_metrics(name, f"estimate {estimate_path}: no positive finite depth "
                              "in it (a depth map of NaN, inf or negative values)")
    judged, flat = visible_in_right(truth), truth.flat()
    if flat is not None:
        judged &= ~flat
    metrics = depth_metrics(est, depth, judged, name, flat)
    changes = truth.changes()
    if changes is None:
        return metrics
    plain = ~np.isfinite(depth) if flat is None else ~np.isfinite(depth) | flat
    return replace(metrics, changes=change_metrics(est, depth, judged, *changes, plain))


def evaluate_scenes(scene_dirs: Iterable[Path], depth_dir: Path | None) -> list[Metrics]:
    return [evaluate_scene(d, find_estimate(depth_dir, d), estimate_candidates(depth_dir, d))
            for d in scene_dirs]


def _mean(values: Sequence[float]) -> float:
    """Mean of the finite values (NaN marks 'not applicable'); NaN if there are none."""
    finite = [v for v in values if math.isfinite(v)]
    return float(np.mean(finite)) if finite else math.nan


def _pct(x: float) -> str:
    return "-" if math.isnan(x) else f"{100 * x:.2f}"


def format_table(rows: Sequence[Metrics]) -> str:
    """A table in the style of the paper's Table 1: one line per scene (percentages of
    judged pixels), the mean and the worst scene, then why any scene failed."""
    header = ["scene", "<0.5%", "<1%", "<2%", "<3%", "density", "bias%", "false%"]
    lines: list[list[str] | None] = []
    for m in rows:
        if m.failed:
            lines.append([m.scene, "FAILED", *["-"] * 6])
            continue
        values = [m.under_0_5, m.under_1, m.under_2, m.under_3, m.density]
        lines.append([m.scene, *(_pct(v) for v in values), f"{100 * m.median_bias:+.3f}",
                      _pct(m.false_depth)])
    ok = [m for m in rows if not m.failed]
    if ok:
        mean = {k: _mean([getattr(m, k) for m in ok]) for k in _FIELDS}
        lines.append(None)
        lines.append(["mean", *(_pct(mean[k]) for k in _FIELDS[:-2]),
                      f"{100 * mean['median_bias']:+.3f}", _pct(mean["false_depth"])])
        lines.append(["worst scene <1%", "", _pct(min(m.under_1 for m in ok)), *[""] * 5])
    text = [render_table(header, lines, left=[0])]
    if any(m.changes is not None for m in rows):
        text.append(_changes_table(rows))
    text += [f"{m.scene}: FAILED: {m.reason}" for m in rows if m.failed]
    text.append(f"failures: {len(rows) - len(ok)} of {len(rows)} scenes")
    return "\n".join(text)


def _changes_table(rows: Sequence[Metrics]) -> str:
    """The scenes where the world moves: static pixels (share of the judged ones, under
    1 %, bias), moved pixels (share of the image, given a depth, given one > 3 % off) and
    pixels only a cloud shadow changes (share, under 1 %)."""
    header = ["scene", "static%", "static<1%", "textured<1%", "bias%", "moved%", "given%",
              "wrong>3%", "shadow%", "shadow<1%"]
    lines: list[list[str] | None] = []
    for m in rows:
        c = m.changes
        if c is None:
            continue
        bias = "-" if math.isnan(c.static_bias) else f"{100 * c.static_bias:+.3f}"
        lines.append([m.scene, _pct(c.static_share), _pct(c.static_under_1),
                      _pct(c.textured_under_1), bias,
                      _pct(c.moved_share), _pct(c.moved_density), _pct(c.moved_wrong),
                      _pct(c.shadow_share), _pct(c.shadow_under_1)])
    title = ("where the world moves: static = judged pixels nothing changed (textured: "
             f"{TEXTURE_MARGIN_PX} px clear of plain ones);\nmoved = pixels a mover covers in "
             "any view, given a depth, given one > 3 % off; shadow = judged pixels only a "
             "cloud shadow changed")
    return title + "\n" + render_table(header, lines, left=[0])


_FIELDS = (
    "under_0_5", "under_1", "under_2", "under_3", "density", "median_bias", "false_depth"
)


def _csv_row(m: Metrics, with_changes: bool) -> dict[str, object]:
    """``m`` as one CSV row; the change scores (NaN where ``m`` has none) only
    ``with_changes``."""
    row: dict[str, object] = {f.name: getattr(m, f.name) for f in fields(Metrics)
                              if f.name != "changes"}
    if with_changes:
        nan = {f.name: math.nan for f in fields(ChangeMetrics)}
        row.update(asdict(m.changes) if m.changes is not None else nan)
    return row


def write_csv(rows: Sequence[Metrics], path: Path) -> None:
    """The table as CSV: one row per scene, the change scores as more columns when any
    scene has them; written whole or not at all, never over a file rigkit did not write
    (:func:`rigkit.core.outputs.write_outputs`)."""
    path.parent.mkdir(parents=True, exist_ok=True)
    with_changes = any(m.changes is not None for m in rows)
    table = [_csv_row(m, with_changes) for m in rows]
    buffer = io.StringIO()
    writer = csv.DictWriter(buffer, fieldnames=list(table[0]), lineterminator="\n")
    writer.writeheader()
    writer.writerows(table)
    write_outputs(path.parent, {path.name: buffer.getvalue()}, "--csv", "eval")


def files_read(scene_dirs: Iterable[Path], depth_dir: Path | None) -> list[Path]:
    """The files an evaluation keeps as they are: every file in each scene folder
    (whether the evaluation reads it or not) and each scene's estimate (the first of
    its candidates that exists)."""
    found = [f for d in scene_dirs if Path(d).is_dir() for f in Path(d).rglob("*")]
    found += [e for d in scene_dirs if (e := find_estimate(depth_dir, Path(d))) is not None]
    return found


GOAL_UNDER_1 = 0.95  # share of judged pixels under 1 % error
GOAL_BIAS = 0.003  # |median bias|
GOAL_TARGET_PCT = 1.0  # every laser target's estimate within this of its range


def goal_line(m: Metrics, scene_dir: Path) -> tuple[bool, str]:
    """Whether scene ``m`` meets the accuracy goal the field protocol is for (at least
    ``GOAL_UNDER_1`` of its judged pixels under 1 % error, |median bias| at most
    ``GOAL_BIAS``, and, for a processed session, every laser target of its latest run
    within ``GOAL_TARGET_PCT``), with one line that says so and by how much."""
    from rigkit.capture.comparisons import read_rows

    if m.failed:
        return False, f"{m.scene}: goal missed: {m.reason}"
    said = [f"{100 * m.under_1:.1f} % of pixels under 1 %", f"bias {100 * m.median_bias:+.2f} %"]
    missed = m.under_1 < GOAL_UNDER_1 or abs(m.median_bias) > GOAL_BIAS
    table = session_comparisons(scene_dir)
    if table.is_file():
        rows = read_rows(table)
        within = sum(math.isfinite(r.error_pct) and abs(r.error_pct) <= GOAL_TARGET_PCT
                     for r in rows)
        said.append(f"{within}/{len(rows)} targets within {GOAL_TARGET_PCT:g} %")
        missed |= within < len(rows)
    goal = (f"goal: >= {100 * GOAL_UNDER_1:.0f} % under 1 %, |bias| <= {100 * GOAL_BIAS:.1f} %"
            f", every target within {GOAL_TARGET_PCT:g} %")
    verdict = "goal missed" if missed else "goal met"
    return not missed, f"{m.scene}: {verdict}: {', '.join(said)} ({goal})"

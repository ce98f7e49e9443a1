"""Table 1 of the paper on our synthetic scenes: four methods, the same scenes, the
same metric (:func:`rigkit.synth.evaluate.depth_metrics`).

Methods: ``rigkit`` (the pipeline as it is), ``paper`` (sec. 4 as written,
:mod:`.paper`), ``loop-zhang`` (:mod:`.loop_zhang`), ``sfm-mvs`` (:mod:`.sfm`). The
three baselines share one set of left/right and left/back matches per scene
(:func:`rigkit.pipeline.features.match_views`); ``rigkit`` computes its own. A method
that produces no depth for a scene counts as a failure, and the shares under each
threshold are averaged over the scenes it did not fail on, as in the paper.
"""

from __future__ import annotations

import csv
import io
import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from rigkit.core.outputs import check_outputs, write_outputs
from rigkit.core.tables import render_table
from rigkit.errors import RigkitError
from rigkit.experiments.defaults import METHODS
from rigkit.experiments.loop_zhang import loop_zhang_depth
from rigkit.experiments.paper import paper_depth
from rigkit.experiments.sfm import sfm_mvs_depth
from rigkit.imagefile.decode import load_grey
from rigkit.pipeline import RigGeometry, estimate_depth
from rigkit.pipeline.features import Matches, match_views
from rigkit.synth import SynthParams, generate_scene, load_scene, write_scene
from rigkit.synth.evaluate import Metrics, depth_metrics, failed_metrics, visible_in_right
from rigkit.synth.io import SceneTruth

VIEWS = ("left", "right", "back")
#: The paper's Table 1 (40 scenes at 4608x3456): failures and % under 1/2/3 %.
PAPER_TABLE1 = {
    "paper": (0, 45.3, 80.1, 96.9),
    "loop-zhang": (0, 1.14, 2.73, 5.99),
    "sfm-mvs": (15, 6.71, 12.7, 19.1),
}
CSV_FIELDS = ("method", "failures", "lt05", "lt1", "lt2", "lt3", "bias")
OUTPUTS = ("table1.csv", "table1_scenes.csv", "table1.png")
"""What :func:`run_table1` writes into its folder."""


@dataclass(frozen=True)
class SceneInput:
    """A rendered scene: its truth, the three (H, W) float32 grey images, and the
    matches the baselines share (None when matching failed, with the reason)."""

    truth: SceneTruth
    images: dict[str, np.ndarray]
    matches: tuple[Matches, Matches] | None
    match_error: str


def scene_dirs(out: Path, seeds: Sequence[int], params: SynthParams) -> list[Path]:
    """``out/scenes/seed-<k>`` for each seed (not rendered yet)."""
    return [out / "scenes" / f"seed-{s}-{params.width}x{params.height}" for s in seeds]


def render_if_missing(folder: Path, seed: int, params: SynthParams) -> None:
    """Render the scene of ``seed`` into ``folder`` unless it is already there."""
    if not (folder / "scene.yaml").is_file():
        write_scene(generate_scene(params, seed), folder)


def load_input(folder: Path) -> SceneInput:
    truth = load_scene(folder)
    images = {v: load_grey(truth.image_path(v)) for v in VIEWS}
    try:
        m_lr = match_views(images["left"], images["right"], "left/right")
        m_lb = match_views(images["left"], images["back"], "left/back")
    except RigkitError as exc:
        return SceneInput(truth, images, None, str(exc))
    return SceneInput(truth, images, (m_lr, m_lb), "")


def run_method(method: str, scene: SceneInput, rng: np.random.Generator) -> np.ndarray:
    """Depth (H, W) float32 m of the scene's left view by ``method``; raises
    RigkitError when the method produces none."""
    t, im = scene.truth, scene.images
    if method == "rigkit":
        rig = RigGeometry(t.focal_px, t.baseline_lr_m, t.baseline_lb_m)
        return estimate_depth(im["left"], im["right"], im["back"], rig).depth
    if scene.matches is None:
        raise RigkitError(scene.match_error)
    m_lr, m_lb = scene.matches
    geometry = (t.focal_px, t.baseline_lr_m, t.baseline_lb_m, rng)
    if method == "paper":
        return paper_depth(im["left"], im["right"], m_lr, m_lb, *geometry)
    if method == "loop-zhang":
        return loop_zhang_depth(im["left"], im["right"], m_lr, m_lb, *geometry)
    K = {v: t.cameras[v].K for v in VIEWS}
    return sfm_mvs_depth(im, K, m_lr, m_lb, t.baseline_lr_m, rng)


def evaluate_scene(
    folder: Path, methods: Sequence[str], seed: int, progress: Callable[[str, float], None]
) -> dict[str, Metrics]:
    """Metrics of each method on one scene folder."""
    progress("matching", 0.0)
    scene = load_input(folder)
    truth_depth = scene.truth.depth("left")
    judged = visible_in_right(scene.truth)
    out = {}
    for i, method in enumerate(methods):
        progress(method, (i + 0.5) / len(methods))
        rng = np.random.default_rng([seed, METHODS.index(method)])
        try:
            depth = run_method(method, scene, rng)
        except RigkitError as exc:
            out[method] = failed_metrics(folder.name, str(exc))
            continue
        out[method] = depth_metrics(depth, truth_depth, judged, folder.name)
    return out


@dataclass(frozen=True)
class MethodRow:
    """One line of Table 1: failures, mean % under 0.5/1/2/3 % over the scenes that did
    not fail, and the mean of the scenes' median signed errors (%)."""

    method: str
    failures: int
    lt05: float
    lt1: float
    lt2: float
    lt3: float
    bias: float


def summarise(method: str, rows: Sequence[Metrics]) -> MethodRow:
    ok = [m for m in rows if not m.failed]

    def mean(key: str) -> float:
        return 100 * float(np.mean([getattr(m, key) for m in ok])) if ok else math.nan

    return MethodRow(
        method, len(rows) - len(ok), mean("under_0_5"), mean("under_1"), mean("under_2"),
        mean("under_3"), mean("median_bias"),
    )


def table_text(rows: Sequence[MethodRow]) -> str:
    """The table, with the paper's numbers beside ours where it has them."""
    header = ["method", "failures", "<0.5%", "<1%", "<2%", "<3%", "bias%", "paper: fail/<1/<2/<3"]

    def pct(x: float) -> str:
        return "-" if math.isnan(x) else f"{x:.2f}"

    lines: list[Sequence[str] | None] = []
    for r in rows:
        ref = PAPER_TABLE1.get(r.method)
        paper = "" if ref is None else f"{ref[0]} / {ref[1]} / {ref[2]} / {ref[3]}"
        lines.append([r.method, str(r.failures), pct(r.lt05), pct(r.lt1), pct(r.lt2),
                      pct(r.lt3), "-" if math.isnan(r.bias) else f"{r.bias:+.3f}", paper])
    return render_table(header, lines, left=[0, 7])


def table_csv(rows: Sequence[MethodRow]) -> str:
    """``table1.csv``: one row per method."""
    buf = io.StringIO()
    writer = csv.writer(buf)
    writer.writerow(CSV_FIELDS)
    for r in rows:
        writer.writerow([r.method, r.failures, *(f"{v:.4f}" for v in
                        (r.lt05, r.lt1, r.lt2, r.lt3, r.bias))])
    return buf.getvalue()


def scenes_csv(per_scene: dict[str, list[Metrics]]) -> str:
    """``table1_scenes.csv``: every scene's metrics per method (fractions, as rigkit
    eval writes them)."""
    buf = io.StringIO()
    fields = ["method", *Metrics.__dataclass_fields__]
    writer = csv.DictWriter(buf, fieldnames=fields)
    writer.writeheader()
    for method, rows in per_scene.items():
        for m in rows:
            writer.writerow({"method": method, **m.__dict__})
    return buf.getvalue()


def figure_png(rows: Sequence[MethodRow], title: str) -> bytes:
    """Grouped bars: % of judged pixels under each threshold per method, with the
    paper's values as black ticks where it reports them."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    fig = Figure(figsize=(8, 4.2), dpi=120)
    FigureCanvasAgg(fig)
    ax = fig.add_subplot()
    labels = ["<0.5%", "<1%", "<2%", "<3%"]
    width = 0.8 / max(len(rows), 1)
    x = np.arange(len(labels))
    for i, r in enumerate(rows):
        vals = np.nan_to_num([r.lt05, r.lt1, r.lt2, r.lt3])
        pos = x + (i - (len(rows) - 1) / 2) * width
        ax.bar(pos, vals, width, label=f"{r.method} ({r.failures} failed)")
        ref = PAPER_TABLE1.get(r.method)
        if ref is not None:
            ax.scatter(pos[1:], ref[1:], marker="_", s=200, color="black", zorder=3)
    ax.scatter([], [], marker="_", s=200, color="black", label="paper's Table 1")
    ax.set_xticks(x, labels)
    ax.set_ylabel("% of judged pixels (mean over scenes)")
    ax.set_ylim(0, 105)
    ax.set_title(title)
    ax.grid(axis="y", alpha=0.3)
    ax.legend(fontsize=8, loc="upper left")
    fig.tight_layout()
    buf = io.BytesIO()
    fig.savefig(buf, format="png")
    return buf.getvalue()


def run_table1(
    out: Path,
    seeds: Sequence[int],
    params: SynthParams,
    methods: Sequence[str] = METHODS,
    progress: Callable[[str, float, str], None] | None = None,
) -> list[MethodRow]:
    """Render (or reuse) the scenes of ``seeds`` under ``out/scenes``, run ``methods``
    on each, write ``table1.csv``, ``table1_scenes.csv`` and ``table1.png`` to ``out``
    and return the table's rows."""
    report = progress or (lambda task, frac, stage: None)
    check_outputs(out, OUTPUTS, "--out", "experiments")  # before the work (rigkit.core.outputs)
    per_scene: dict[str, list[Metrics]] = {m: [] for m in methods}
    for seed, folder in zip(seeds, scene_dirs(out, seeds, params), strict=True):
        name = folder.name
        report(name, 0.0, "rendering")
        render_if_missing(folder, seed, params)

        def stage(st: str, frac: float, name: str = name) -> None:
            report(name, frac, st)

        scores = evaluate_scene(folder, methods, seed, stage)
        for method, m in scores.items():
            per_scene[method].append(m)
        report(name, 1.0, "done")
    rows = [summarise(m, per_scene[m]) for m in methods]
    title = f"{len(seeds)} scenes at {params.width}x{params.height}"
    contents = (table_csv(rows), scenes_csv(per_scene), figure_png(rows, title))
    write_outputs(out, dict(zip(OUTPUTS, contents, strict=True)), "--out", "experiments")
    return rows

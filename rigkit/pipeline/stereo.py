"""Stage 2: dense disparity on the rectified pair.

The default matcher is OpenCV's semi-global matching (Hirschmueller 2008) with
sub-pixel interpolation, a left-right consistency check (the right view's disparity
comes from matching the mirrored pair, half a pixel apart, and the two passes are
averaged where they agree) and speckle filtering, run on fixed bands of rows side by
side (:func:`bands`). Any object with the :class:`StereoMatcher` signature can replace
it.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Protocol

import cv2
import numpy as np

from rigkit.core.threads import ViewPool


class StereoMatcher(Protocol):
    def __call__(
        self, left: np.ndarray, right: np.ndarray, disparity_range: tuple[int, int]
    ) -> np.ndarray:
        """left, right: (H, W) float32 rectified grey images; disparity_range: (lo, hi) px.

        Returns disparity (H, W) float32, px, ``x_left - x_right``, NaN where unknown."""
        ...


BAND_ROWS = 384
"""Rows of the stereo canvas each band of :class:`SGBM` gives (:func:`bands`): a
full-resolution canvas (~1730 rows at half scale) is 5 bands, 10 passes side by side."""
BAND_ABOVE = 32
"""Rows above its own that a band is matched with and then drops: semi-global matching's
paths from the top start there, so that they have settled by the band's first row.
OpenCV splits each call into 4 stripes of its own (whatever the number of threads),
which overlap by 3 rows and a tenth of a stripe: 14 rows in a band."""
BAND_BELOW = 8
"""Rows below its own that a band is matched with and then drops: the matching window,
the median filter and the speckle filter look a few rows down."""


def bands(height: int) -> list[tuple[int, int]]:
    """The bands (first row, row after the last) that :class:`SGBM` matches side by side,
    for a canvas of ``height`` rows: ``BAND_ROWS`` each, the last one taking in a
    remainder of under half a band. The layout depends on the canvas alone, never on
    the number of cores or threads, so the disparities are the same on any machine."""
    starts = list(range(0, height, BAND_ROWS))
    if len(starts) > 1 and height - starts[-1] < BAND_ROWS // 2:
        starts.pop()
    return [(r0, r1) for r0, r1 in zip(starts, [*starts[1:], height], strict=True)]


@dataclass(frozen=True)
class SGBM:
    """Semi-global block matching with a left-right check (CPU, OpenCV), on the bands
    of :func:`bands`, each matched with ``BAND_ABOVE`` and ``BAND_BELOW`` rows of context
    in a :class:`rigkit.core.threads.ViewPool` (each band's two passes and their merge
    are its own: only the band's own rows are kept)."""

    block_size: int = 5
    uniqueness: int = 5
    lr_tolerance_px: float = 1.0
    speckle_window: int = 100
    speckle_range_px: int = 2

    def _matcher(self, lo: int, n: int) -> cv2.StereoSGBM:
        b = self.block_size
        return cv2.StereoSGBM_create(  # type: ignore[attr-defined]
            minDisparity=lo,
            numDisparities=n,
            blockSize=b,
            P1=8 * b * b,
            P2=32 * b * b,
            disp12MaxDiff=-1,
            preFilterCap=31,
            uniquenessRatio=self.uniqueness,
            speckleWindowSize=self.speckle_window,
            speckleRange=self.speckle_range_px * 16,
            mode=cv2.STEREO_SGBM_MODE_SGBM_3WAY,
        )

    def __call__(
        self, left: np.ndarray, right: np.ndarray, disparity_range: tuple[int, int]
    ) -> np.ndarray:
        lo, hi = disparity_range
        n = max(16, int(np.ceil((hi - lo) / 16.0)) * 16)
        h = left.shape[0]
        out = np.empty(left.shape, np.float32)
        with ViewPool() as pool:
            passes = []
            for r0, r1 in bands(h):
                rows = slice(max(r0 - BAND_ABOVE, 0), min(r1 + BAND_BELOW, h))
                keep = slice(r0 - rows.start, r1 - rows.start)
                direct, mirrored = (pool.submit(self._pass, left[rows], right[rows], lo, n,
                                                mirror, keep) for mirror in (False, True))
                passes.append((slice(r0, r1), direct, mirrored))
            for band, direct, mirrored in passes:
                out[band] = _merge_passes(direct.result(), mirrored.result(),
                                          self.lr_tolerance_px)
        return out

    def _pass(self, left: np.ndarray, right: np.ndarray, lo: int, n: int, mirrored: bool,
              keep: slice) -> np.ndarray:
        """One pass of semi-global matching on a band of rows ((h, w) float32 each),
        for disparities from ``lo`` over ``n`` (a multiple of 16): the left view's
        disparities (px, ``x_left - x_right``), or with ``mirrored`` the right view's
        after its image moved ``HALF_PX`` to the right (see :func:`_merge_passes`); NaN
        where none. Only the rows ``keep`` are returned."""
        # SGBM leaves the first lo+n columns unmatched (and the mirrored pass the last
        # ones): pad both images so that band falls outside the picture.
        pad = n + abs(lo)
        l8, r8 = (
            cv2.copyMakeBorder(
                np.clip(np.rint(im), 0, 255).astype(np.uint8), 0, 0, pad, pad, cv2.BORDER_REPLICATE
            )
            for im in (left, right)
        )
        if not mirrored:
            raw = self._matcher(lo, n).compute(l8, r8)[keep, pad:-pad]
            return np.where(raw >= lo * 16, raw / np.float32(16), np.float32(np.nan))
        # Right view's disparity: mirroring both images and swapping them keeps the sign
        # of x_left - x_right, so the same matcher applies; mirror the result back. The
        # right image moves half a pixel to the right first, so that this pass's
        # disparities are HALF_PX smaller and their pull towards whole pixels is the
        # opposite of the left pass's (see _merge_passes).
        shifted = cv2.warpAffine(r8, np.array([[1.0, 0.0, HALF_PX], [0.0, 1.0, 0.0]]),
                                 (r8.shape[1], r8.shape[0]), flags=cv2.INTER_LINEAR,
                                 borderMode=cv2.BORDER_REPLICATE)
        raw_r = self._matcher(lo - 1, n).compute(shifted[:, ::-1].copy(), l8[:, ::-1].copy())
        raw_r = raw_r[keep, ::-1][:, pad:-pad]
        return np.where(raw_r >= (lo - 1) * 16, raw_r / np.float32(16), np.float32(np.nan))


def _at_match(disp: np.ndarray, right_map: np.ndarray, fill: float) -> np.ndarray:
    """``right_map`` (H, W; float32, or bool) looked up at each left pixel's match
    ``(row, x - d)`` (nearest column, halves to even); ``fill`` where the disparity is
    NaN or the match is off the image. One nearest-neighbour remap: the columns are
    multiples of 1/32 px, exact in float32."""
    h, w = disp.shape
    xs = np.arange(w, dtype=np.float32)[None, :] - np.nan_to_num(disp, nan=-1e6)
    ys = np.repeat(np.arange(h, dtype=np.float32)[:, None], w, axis=1)
    flag = right_map.dtype == np.bool_
    src = right_map.view(np.uint8) if flag else right_map
    out = cv2.remap(src, xs, ys, cv2.INTER_NEAREST, borderMode=cv2.BORDER_CONSTANT,
                    borderValue=fill)
    return out.view(np.bool_) if flag else out


HALF_PX = 0.5  # the right image's shift before the mirrored pass


def _merge_passes(disp: np.ndarray, disp_r: np.ndarray, tol: float) -> np.ndarray:
    """The left pass's disparities (H, W) that the mirrored pass confirms within ``tol``
    px, averaged with it; NaN elsewhere. ``disp_r`` (H, W) holds the right view's
    disparities after its image moved ``HALF_PX`` to the right: a left pixel's match is
    then at ``x - d + HALF_PX``, with disparity ``d - HALF_PX``.

    Semi-global matching interpolates its sub-pixel disparity between the costs of whole
    pixels, which its smoothness penalties flatten, so the result is drawn towards whole
    pixels ("pixel locking"; Shimizu and Okutomi 2005 cancel it with a second match half
    a pixel apart, as here). On a small rendered scene whose true disparities sat 0.25-
    0.5 stereo px from a whole pixel, the left pass alone was 0.24 px off, in one
    direction, and where they sat at the other side, in the other; which side depends on
    where the rectification happens to put the disparities. The mirrored pass, half a
    pixel apart, is drawn the other way, and the average cancels most of it: the median
    error there fell from 0.19 to 0.05 stereo px (docs/results-log.md, "Tracking local
    contrast; the stereo passes half a pixel apart"). It costs one shift of an 8-bit
    image."""
    with np.errstate(invalid="ignore"):
        other = _at_match(disp - np.float32(HALF_PX), disp_r, np.nan) + np.float32(HALF_PX)
        ok = np.abs(other - disp) <= tol
    return np.where(ok, np.float32(0.5) * (disp + other), np.float32(np.nan)).astype(
        np.float32, copy=False)


def restrict_to_footprints(
    disp: np.ndarray, left_valid: np.ndarray, right_valid: np.ndarray,
    surface: np.ndarray | None = None,
) -> np.ndarray:
    """NaN where the left pixel, or its match ``x - d`` in the right image, lies outside
    that image's footprint on the rectified canvas, and where ``surface`` is False (all
    (H, W); masks bool; None: everywhere a surface). Bands of ``ROWS`` rows side by side
    (each row's matches lie in the row)."""
    out = np.empty(disp.shape, np.float32)

    def band(r0: int) -> None:
        rows = slice(r0, r0 + ROWS)
        d = disp[rows] if surface is None else np.where(surface[rows], disp[rows], np.nan)
        ok = _at_match(d, right_valid[rows], 0) & left_valid[rows]
        np.copyto(out[rows], np.where(ok, d, np.float32(np.nan)))

    with ViewPool() as pool:
        pool.map(band, range(0, disp.shape[0], ROWS))
    return out


ROWS = 128
"""Rows of the canvas per piece of the work that is done row by row (:func:`fill_holes`,
:func:`restrict_to_footprints`), the pieces spread over a
:class:`rigkit.core.threads.ViewPool`: every row comes out as from the whole canvas."""


def surface_mask(
    image: np.ndarray, inside: np.ndarray, min_texture: float, window: int
) -> np.ndarray:
    """Where ``image`` shows a surface that can be matched: (h, w) bool.

    A pixel has no surface to match when the horizontal contrast in the ``window``
    around it (RMS of the Sobel x-derivative, scaled to grey levels) is below
    ``min_texture`` times the image noise at its brightness, or when it is clipped
    white: sky, haze-blank background, blank walls and blown highlights. Semi-global
    matching would otherwise spread its neighbours' disparities into them. The mask is
    eroded by the window, which drops islands smaller than it (noise that happens to
    pass) and the half window that the contrast measure spreads beyond an edge; it
    cannot clear gaps narrower than the window between thin structures, which
    :func:`clipped_black` clears where they show an exactly black backdrop.

    image: (h, w) float32 grey, 0-255; inside: (h, w) bool, where ``image`` has content.
    Returns (h, w) bool.
    """
    k = (window, window)
    gx = cv2.Sobel(image, cv2.CV_32F, 1, 0, ksize=3) / np.float32(np.sqrt(12.0))
    contrast = np.sqrt(np.maximum(cv2.boxFilter(gx * gx, -1, k), 0))
    core = cv2.erode(inside.astype(np.uint8), np.ones(k, np.uint8)) > 0
    if not core.any():
        return np.zeros(image.shape, bool)
    mean = cv2.boxFilter(image, -1, k)
    noise = _noise_level(image, mean, core, k)
    clipped = cv2.dilate((image >= 254).astype(np.uint8), np.ones((3, 3), np.uint8)) > 0
    raw = (contrast >= min_texture * noise) & ~clipped & inside
    # The window spreads a textured edge half a window into the blank area beside it;
    # eroding by the window takes that back, and drops islands smaller than it. The
    # image border is no blank area: outside counts as surface while eroding.
    eroded = cv2.erode((raw | ~inside).astype(np.uint8), np.ones(k, np.uint8)) > 0
    return eroded & inside


def clipped_black(image: np.ndarray) -> np.ndarray:
    """Where ``image`` is clipped to black over an area: (H, W) bool.

    A pixel at exactly 0 measures nothing, it only bounds: a shadow or a night sky
    below the black level, an empty rendered backdrop. :func:`surface_mask` cannot see
    that on the stereo canvas. Its window (``texture_window_px``, at half resolution
    18 px of the image) is wider than a hair, a wire or a twig, so between thin
    structures spaced closer than that every black pixel's window holds texture, and
    semi-global matching gives it their disparity; the erosion that takes the half
    window back beside an edge only clears gaps wider than the window. Whether there
    is noise makes no difference: on the authors' elephant scene (hairs radiating into
    an exactly black backdrop), 16.4 % of the backdrop got a depth without noise and
    16.3 % with noise of 2 grey levels on the elephant (docs/results-log.md). The
    recorded image says which pixels show nothing, at its own resolution.

    An area, not a sample: the 8-connected sets of zeros that hold at least one 3 x 3
    block of zeros. The scattered zeros of a dark surface whose noise reaches below
    the black level are samples of that surface, not an area, and stay.

    image: (H, W) float32 grey, 0-255, as recorded (not the stereo canvas).
    """
    zero = (image <= 0).astype(np.uint8)
    seeds = cv2.erode(zero, np.ones((3, 3), np.uint8))  # centres of 3 x 3 blocks of zeros
    if not seeds.any():
        return np.zeros(image.shape, bool)
    n, labels = cv2.connectedComponents(zero, connectivity=8)
    area = np.zeros(n, bool)
    area[labels[seeds > 0]] = True
    area[0] = False  # label 0: the pixels that are not zero
    return area[labels]


def _noise_level(
    image: np.ndarray, mean: np.ndarray, core: np.ndarray, k: tuple[int, int], bins: int = 12
) -> np.ndarray:
    """The image noise (grey levels) as a function of brightness, at every pixel:
    (h, w) float32. Noise grows with brightness (shot noise), so a single figure
    under-rates it in a bright sky. Following the lower-envelope idea of Liu et al.
    (2006), the noise at a brightness is the 5th percentile of the local noise measured
    with Immerkaer's (1996) Laplacian-difference operator among pixels of that
    brightness (texture only raises the measure), made non-decreasing in brightness."""
    lap = np.array([[1, -2, 1], [-2, 4, -2], [1, -2, 1]], np.float32)
    local = cv2.boxFilter(np.abs(cv2.filter2D(image, -1, lap)), -1, k) * np.float32(
        np.sqrt(np.pi / 2) / 6
    )
    # Every other row and column is sample enough for these percentiles (a million
    # pixels on a full-resolution canvas) at a quarter of the cost.
    m, n = (a[::2, ::2][core[::2, ::2]] for a in (mean, local))
    edges = np.unique(np.percentile(m, np.linspace(0, 100, bins + 1)))
    centres, levels = [], []
    for lo, hi in zip(edges[:-1], edges[1:], strict=True):
        sel = (m >= lo) & (m <= hi)
        if sel.sum() >= 50:
            centres.append(0.5 * (lo + hi))
            levels.append(float(np.percentile(n[sel], 5)))
    if not centres:  # too few pixels to bin: one level for the whole image
        return np.full(image.shape, max(float(np.percentile(n, 5)), 0.25), np.float32)
    envelope = np.maximum.accumulate(np.maximum(levels, 0.25))
    return np.interp(mean, centres, envelope).astype(np.float32)


def fill_holes(
    disp: np.ndarray, max_gap: int, barrier: np.ndarray | None = None
) -> tuple[np.ndarray, np.ndarray]:
    """Fill gaps of at most ``max_gap`` px along rows with the farther (smaller-disparity)
    of the two valid neighbours, as Hirschmueller (2008) does for occlusions: a hole
    next to a depth edge belongs to the occluded background. Gaps that touch the image
    border, or a ``barrier`` pixel (where the views disagree: nothing there may be
    carried across), are left NaN.

    disp: (H, W) float32 with NaN holes; barrier: (H, W) bool or None.
    Returns (filled disparity, bool mask of filled). Bands of ``ROWS`` rows side by side.
    """
    out, hole = np.empty(disp.shape, disp.dtype), np.empty(disp.shape, bool)

    def band(r0: int) -> None:
        rows = slice(r0, r0 + ROWS)
        out[rows], hole[rows] = _fill_rows(disp[rows], max_gap,
                                           None if barrier is None else barrier[rows])

    with ViewPool() as pool:
        pool.map(band, range(0, disp.shape[0], ROWS))
    return out, hole


def _fill_rows(
    disp: np.ndarray, max_gap: int, barrier: np.ndarray | None
) -> tuple[np.ndarray, np.ndarray]:
    """:func:`fill_holes` of some rows."""
    h, w = disp.shape
    valid = np.isfinite(disp)
    end = valid if barrier is None else valid | barrier
    idx = np.broadcast_to(np.arange(w), (h, w))
    prev_i = np.maximum.accumulate(np.where(end, idx, -1), axis=1)
    next_i = np.minimum.accumulate(np.where(end, idx, w)[:, ::-1], axis=1)[:, ::-1]
    gap = next_i - prev_i - 1
    hole = ~end & (prev_i >= 0) & (next_i < w) & (gap <= max_gap)
    rows = np.broadcast_to(np.arange(h)[:, None], (h, w))
    hr, pi, ni = rows[hole], prev_i[hole], next_i[hole]
    if barrier is not None:  # both ends must be matched pixels, not a barrier
        ok = valid[hr, pi] & valid[hr, ni]
        hole[hole] = ok
        hr, pi, ni = hr[ok], pi[ok], ni[ok]
    out = disp.copy()
    out[hole] = np.minimum(disp[hr, pi], disp[hr, ni])
    return out, hole

"""Stage -1: several frames of one camera position stacked into one image.

Heat shimmer moves every isoplanatic patch of the image by a fraction of a pixel, and
frames taken a moment apart see independent shimmer (docs/pipeline.md, "Heat
shimmer"). The per-pixel median of N frames puts each patch near its mean position,
cutting the displacement by ~sqrt(N), and averages the sensor noise. The frames are
first aligned to the first one by a global sub-pixel translation (phase correlation on
the most textured crop), which is all that a tripod moves between shots of a burst.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from contextlib import nullcontext

import cv2
import numpy as np

from rigkit.core.threads import ViewPool
from rigkit.errors import InputError

CROP = 1024  # side of the crop the shift is measured on, px
MAX_SHIFT_PX = 50.0  # a larger shift is not one tripod position


def stack_burst(frames: Sequence[np.ndarray], what: str = "burst") -> np.ndarray:
    """One (H, W) float32 image from a burst of (H, W) float32 grey frames of one
    position: each aligned to the first, then the per-pixel median. A single frame is
    returned as it is. Raises InputError for frames of different sizes or frames that
    do not show the same view (``what`` names the position in the message)."""
    if len(frames) == 1:
        return frames[0]
    ref = frames[0]
    crop = textured_crop(ref, CROP)  # once for the burst

    def aligned(i: int, frame: np.ndarray) -> np.ndarray:
        if frame.shape != ref.shape:
            raise InputError(
                f"{what}: frame {i} is {frame.shape[1]}x{frame.shape[0]}, frame 1 is "
                f"{ref.shape[1]}x{ref.shape[0]}"
            )
        dx, dy = _shift_in(ref, frame, crop)
        if np.hypot(dx, dy) > MAX_SHIFT_PX:
            raise InputError(
                f"{what}: frame {i} is shifted by ({dx:+.0f}, {dy:+.0f}) px from frame 1; "
                "all frames of a burst must come from one camera position"
            )
        return shifted(frame, dx, dy)

    with ViewPool() as pool:  # each frame on its own; the first problem in order is raised
        return median([ref, *pool.map(aligned, range(2, len(frames) + 1), frames[1:])],
                      pool=pool)


def median(frames: Sequence[np.ndarray], rows: int = 32, pool: ViewPool | None = None
           ) -> np.ndarray:
    """Per-pixel median of N same-shape (H, W) float32 frames (the mean of the two
    middle values for even N, as :func:`numpy.median`); ``frames`` are left unchanged.

    Each block of ``rows`` rows is sorted across the frames by an odd-even
    transposition network of element-wise min/max (N rounds; Knuth, TAOCP vol. 3,
    5.3.4), small enough to stay in cache, less the halves of its compare-exchanges
    whose result the middle never reads (:func:`_median_network`: 14 of 20 for 5
    frames). :func:`numpy.median` over a stacked axis
    selects within each pixel's N values one pixel at a time: at 16 MP this is ~25x
    faster for 5 frames and ~13x for 16. Pieces of ``PIECE_ROWS`` rows run in ``pool``'s
    threads where one is given.
    """
    n, mid = len(frames), len(frames) // 2
    height = frames[0].shape[0]
    out = np.empty(frames[0].shape, np.float32)
    network = _median_network(n)

    def blocks(r0: int) -> None:
        for b0 in range(r0, min(r0 + PIECE_ROWS, height), rows):
            _median_block(frames, out, slice(b0, min(b0 + rows, r0 + PIECE_ROWS, height)),
                          network, mid)

    # Pieces of rows in threads (a pool's, where given): each block is its own.
    with nullcontext(pool) if pool is not None else ViewPool(1) as run:
        run.map(blocks, range(0, height, PIECE_ROWS))
    return out


PIECE_ROWS = 256
"""Rows of :func:`median`'s pieces, spread over a pool's threads."""


def _median_network(n: int) -> list[tuple[int, bool, bool]]:
    """The compare-exchanges of the odd-even transposition network on ``n`` values that
    the median (the middle one, or the two middle ones for even ``n``) depends on, in
    order: (i, lower, upper) sorts places i and i + 1, ``lower``: the smaller value is
    read later (into place i), ``upper``: the larger (into i + 1). Found backwards from
    the middle; min and max only pick values, so the median is the full sort's, bit
    for bit."""
    mid = n // 2
    read = {mid} if n % 2 else {mid - 1, mid}
    network = []
    for rnd in reversed(range(n)):
        for i in range(rnd % 2, n - 1, 2):
            lower, upper = i in read, i + 1 in read
            if lower or upper:
                network.append((i, lower, upper))
                read |= {i, i + 1}
    return network[::-1]


def _median_block(frames: Sequence[np.ndarray], out: np.ndarray, block_rows: slice,
                  network: list[tuple[int, bool, bool]], mid: int) -> None:
    """:func:`median`'s rows ``block_rows`` into ``out`` through ``network``
    (:func:`_median_network`)."""
    vals = [np.array(f[block_rows], dtype=np.float32) for f in frames]  # copies
    spare = np.empty_like(vals[0])
    for i, lower, upper in network:
        if not upper:
            np.minimum(vals[i], vals[i + 1], out=vals[i])
        elif not lower:
            np.maximum(vals[i], vals[i + 1], out=vals[i + 1])
        else:
            np.minimum(vals[i], vals[i + 1], out=spare)
            np.maximum(vals[i], vals[i + 1], out=vals[i + 1])
            vals[i], spare = spare, vals[i]
    n = len(frames)
    block = out[block_rows]
    if n % 2:
        block[:] = vals[mid]
    else:
        np.add(vals[mid - 1], vals[mid], out=block)
        block *= np.float32(0.5)


CUBIC_A = -0.75
"""Keys' bicubic kernel parameter (OpenCV's INTER_CUBIC)."""


def shifted(frame: np.ndarray, dx: float, dy: float) -> np.ndarray:
    """``frame`` resampled at (x + dx, y + dy) for every pixel (x, y): (H, W) float32,
    Keys' bicubic interpolation (``CUBIC_A``), the edges replicated: OpenCV's
    INTER_CUBIC translation (``cv2.warpAffine``), within 1e-4 of the values' range
    (OpenCV rounds the coordinates it samples at). A translation is separable: two
    4-tap filters, half ``cv2.warpAffine``'s time at 16 MP."""
    h, w = frame.shape
    (ix, kx), (iy, ky) = _cubic_taps(dx), _cubic_taps(dy)
    # Output pixel x reads columns x + ix - 1 ... x + ix + 2 (rows likewise): a border
    # replicated as wide as that needs, then a window whose pixel x is column x + ix - 1.
    pad = (max(0, 1 - iy), max(0, iy + 2), max(0, 1 - ix), max(0, ix + 2))
    padded = cv2.copyMakeBorder(frame, *pad, cv2.BORDER_REPLICATE)
    y0, x0 = iy - 1 + pad[0], ix - 1 + pad[2]
    window = padded[y0 : y0 + h + 3, x0 : x0 + w + 3]
    out = cv2.sepFilter2D(window, cv2.CV_32F, kx, ky, anchor=(0, 0),
                          borderType=cv2.BORDER_REPLICATE)
    return np.asarray(out[:h, :w])


def _cubic_taps(shift: float) -> tuple[int, np.ndarray]:
    """(i, taps): resampling at x + ``shift`` is sum_k taps[k] * image(x + i - 1 + k),
    k = 0...3; taps (4,) float32, Keys' kernel at the fraction of ``shift``."""
    whole = math.floor(shift)
    t = shift - whole
    d = np.array([1.0 + t, t, 1.0 - t, 2.0 - t])
    a = CUBIC_A
    near = ((a + 2) * d - (a + 3)) * d * d + 1  # |d| <= 1
    far = ((a * d - 5 * a) * d + 8 * a) * d - 4 * a  # 1 < |d| < 2
    return whole, np.where(d <= 1.0, near, far).astype(np.float32)


def frame_shift(ref: np.ndarray, frame: np.ndarray) -> tuple[float, float]:
    """(dx, dy) px such that ``frame(x + dx, y + dy) ~ ref(x, y)``: the tripod's sway
    between two (H, W) frames of one position, by phase correlation on the most
    textured crop of ``ref`` (a plain wall in the middle of the frame has nothing to
    correlate: on one, the central crop gave shifts of 75-136 px for frames that had
    not moved)."""
    return _shift_in(ref, frame, textured_crop(ref, CROP))


def _shift_in(ref: np.ndarray, frame: np.ndarray, crop: tuple[slice, slice]) -> tuple[float, float]:
    """:func:`frame_shift` measured on ``crop`` (rows, columns) of both frames."""
    size = (crop[1].stop - crop[1].start, crop[0].stop - crop[0].start)
    window = cv2.createHanningWindow(size, cv2.CV_32F)
    # Copies: OpenCV windows its inputs in place, and a crop of the whole frame is a view.
    (dx, dy), _ = cv2.phaseCorrelate(
        np.array(ref[crop], np.float32), np.array(frame[crop], np.float32), window
    )
    return float(dx), float(dy)


def textured_crop(image: np.ndarray, side: int, step: int = 8) -> tuple[slice, slice]:
    """The ``side`` x ``side`` crop (clipped to the image) of the (H, W) ``image`` with the
    most gradient energy, searched on a grid of ``step`` px in an image reduced by
    ``step``: (rows, columns) slices."""
    h, w = image.shape
    sh, sw = min(side, h), min(side, w)
    small = cv2.resize(image, (max(w // step, 1), max(h // step, 1)),
                       interpolation=cv2.INTER_AREA).astype(np.float32)
    energy = cv2.Sobel(small, cv2.CV_32F, 1, 0) ** 2 + cv2.Sobel(small, cv2.CV_32F, 0, 1) ** 2
    kh, kw = max(sh // step, 1), max(sw // step, 1)
    total = cv2.boxFilter(energy, -1, (kw, kh), anchor=(0, 0), normalize=False,
                          borderType=cv2.BORDER_CONSTANT)
    valid = total[: small.shape[0] - kh + 1, : small.shape[1] - kw + 1]
    y, x = np.unravel_index(int(np.argmax(valid)), valid.shape)
    y0, x0 = min(y * step, h - sh), min(x * step, w - sw)
    return slice(y0, y0 + sh), slice(x0, x0 + sw)

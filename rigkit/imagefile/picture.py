"""Is there a picture in a decoded frame? Refusing frames that decode to nothing.

A file can decode without error and still hold no photograph: a DNG whose image data
was stripped decodes to zeros, a damaged RAW stream to a pattern of stripes or noise, a
film scanner's NEF to a white field, a JPEG cut short to grey rows below the point where
the copy stopped. Any of them would go through the pipeline and come out as a
confident, made-up depth map, so a frame is checked once it is decoded, on arrival and
again before depth is computed, and refused with what is wrong and what to do.

The checks and their thresholds (measured on the real files in ../shared/data/real-raw
and on rendered frames; docs/sessions.md, "Frames with no picture"):

* **white**: more than half of the frame clipped white (the film scanner's NEF: 87 %).
  A bright sky clips a part of a frame, not most of it; the on-site exposure check
  already asks for a retake above 1 %.
* **blank**: all pixels one value (stripped DNGs decode to exact zeros). A real frame,
  however dark, carries sensor noise of several levels; the threshold is a few 16-bit
  levels of spread between the 0.1st and 99.9th percentile.
* **noise**: no structure beyond the pixel scale. Averaging 8x8 blocks keeps nearly all
  of a photograph's variance (0.79-0.99 of it on real and rendered frames; still 0.18
  when noise per pixel is twice the scene's contrast) but 1/64 of white noise's.
* **cut short**: the bottom rows are one flat value across the whole width, neither
  black nor white: what a JPEG decoder fills in after the data ends (the decoders'
  own complaints are read too, :func:`rigkit.imagefile.decode.check_decoder_output`).
"""

from __future__ import annotations

import numpy as np

BLANK_SPREAD = 4.0 / 65535.0
"""Largest 0.1-99.9 percentile spread (fraction of full scale) of a blank frame."""
MAX_CLIPPED = 0.5
"""Largest fraction of a frame clipped white for it to still hold a picture."""
CLIP_LEVEL = 0.995
"""Grey level (fraction of full scale) from which a pixel counts as clipped."""
MIN_STRUCTURE = 0.05
"""Least fraction of a frame's variance that 8x8 block means keep (white noise: 1/64)."""
STRUCTURE_BLOCK = 8
MIN_CUT_ROWS = 0.01
"""A flat band at the bottom this tall (fraction of the height) or taller is a cut."""
_SAMPLE_PX = 1024
"""The statistics are taken on at most this many rows and columns (a regular subset,
or for the structure a central crop): about 10 ms for a 16 MP frame."""


def picture_problem(grey: np.ndarray) -> str | None:
    """Why ``grey`` ((H, W) float32 in [0, 1], a decoded frame) holds no picture, as a
    phrase for an error line; None when it holds one."""
    grey = np.asarray(grey, dtype=np.float32)
    step = max(1, -(-max(grey.shape) // _SAMPLE_PX))
    sample = grey[::step, ::step]
    clipped = float(np.mean(sample >= CLIP_LEVEL))
    if clipped > MAX_CLIPPED:
        return (f"{100 * clipped:.0f} % of it is clipped white: it was grossly overexposed, or "
                "is not a photograph")
    low, high = np.percentile(sample, [0.1, 99.9])
    if high - low <= BLANK_SPREAD:
        return (f"it is blank (every pixel {float(np.median(sample)):.3g} of full scale): the "
                "image data is missing or the lens was capped")
    cut = _flat_bottom_rows(grey)
    if cut >= MIN_CUT_ROWS * grey.shape[0]:
        return (f"its last {cut} rows are one flat grey: the file was cut short (copy it "
                "from the card again)")
    structure = _structure(grey)
    if structure < MIN_STRUCTURE:
        return (f"it is noise with no picture in it (8x8 blocks keep {100 * structure:.1f} % "
                "of its variance, a photograph most of it): a damaged file, or a frame of fog or "
                "blank sky")
    return None


def _flat_bottom_rows(grey: np.ndarray) -> int:
    """How many rows at the bottom are all one value, neither black nor clipped."""
    last = grey[-1]
    value = float(last[0])
    if not 0.0 < value < CLIP_LEVEL or not np.all(last == value):
        return 0
    rows = 1
    while rows < grey.shape[0] and np.all(grey[-rows - 1] == value):
        rows += 1
    return rows


def _structure(grey: np.ndarray) -> float:
    """Fraction of the variance of ``grey`` that its STRUCTURE_BLOCK-square block means
    keep (on a central crop of at most _SAMPLE_PX square)."""
    k = STRUCTURE_BLOCK
    h, w = (min(side, _SAMPLE_PX) // k * k for side in grey.shape)
    y0, x0 = (grey.shape[0] - h) // 2, (grey.shape[1] - w) // 2
    crop = grey[y0 : y0 + h, x0 : x0 + w].astype(np.float64)
    total = crop.var()
    if total == 0.0:
        return 1.0
    blocks = crop.reshape(h // k, k, w // k, k).mean(axis=(1, 3))
    return float(blocks.var() / total)

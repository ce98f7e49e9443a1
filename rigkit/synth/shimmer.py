"""Heat shimmer: the random image displacement field turbulence gives one frame.

Three spectra (``SynthParams.shimmer_spectrum``), each field scaled to an RMS of
``rms_px`` per axis; the two axes are independent draws:

* ``gaussian`` (the default): white noise blurred by a Gaussian of sigma ``corr_px``,
  one correlation length (:func:`shimmer_field`).
* ``fine``: half the variance as ``gaussian``, half with a correlation length
  ``FINE_RATIO`` times shorter (at least 0.5 px): detail that moves neighbouring
  pixels apart, on top of the smooth warp.
* ``vonkarman``: a power law with an outer scale, as turbulence has. The power spectral
  density of each displacement component is the von Karman form

      W(f) = c (f^2 + 1 / L0^2)^(-11/6),       f in cycles/px, L0 the outer scale, px

  Kolmogorov's -11/3 law of the refractive-index fluctuations, flattened below 1/L0
  (von Karman's modification; e.g. Andrews & Phillips, *Laser Beam Propagation through
  Random Media*, 2nd ed., SPIE 2005, ch. 3, Phi_n = 0.033 Cn^2 (kappa^2 +
  kappa_0^2)^(-11/6) with kappa = 2 pi f). Since ``int W 2 pi f df`` converges to
  ``(6/5) pi c L0^(5/3)``, the share of the variance at spatial frequencies above
  ``f`` is ``(1 + (f L0)^2)^(-5/6)``: with L0 = 1500 px, 1.1 % above 1/100 px^-1 and
  0.02 % above 1/10 px^-1. Most of the motion is a large-scale tilt and warp of the
  whole frame; the scaling to ``rms_px`` sets ``c``. (The angle of arrival through one
  aperture, the wavefront's gradient averaged over it, has the per-axis pupil-plane
  spectrum ``f_x^2 (f^2 + 1/L0^2)^(-11/6)`` times the aperture's filter - Conan, Rousset
  & Madec, JOSA A 12, 1995 - with more of its variance at small scales: see
  docs/synthetic-scenes.md.)

The von Karman field is drawn on a periodic grid (white noise filtered by ``sqrt(W)``
with FFTs) one period of which holds the image and 4 L0 more, so that opposite edges of
the image are not correlated by the wrap-around. Its points are ``step`` px apart, as
few as keep it within ``GRID_MAX`` a side but no coarser than L0 / 128: the variance
above its Nyquist frequency, ``(1 + (L0 / 2 step)^2)^(-5/6)``, stays under 0.1 %. It is
interpolated (bicubic) to the image's pixels.
"""

from __future__ import annotations

import math

import cv2
import numpy as np
from scipy import fft as sfft

SPECTRA = ("gaussian", "fine", "vonkarman")
FINE_RATIO = 8.0  # fine: the short correlation length is corr_px / FINE_RATIO
GRID_MAX = 1024  # vonkarman: grid points per side, unless the outer scale needs more


def shimmer_field(
    shape: tuple[int, int], rms_px: float, corr_px: float, rng: np.random.Generator
) -> tuple[np.ndarray, np.ndarray]:
    """A smooth random displacement field (dx, dy), each (H, W) float32 px with RMS
    ``rms_px`` and a Gaussian correlation of sigma ``corr_px``: the image shift that
    turbulence gives each isoplanatic patch at one instant."""
    h, w = shape
    step = max(1, int(corr_px / 4))
    small = (-(-h // step) + 1, -(-w // step) + 1)
    out = []
    for _ in range(2):
        white = rng.standard_normal(small).astype(np.float32)
        field = cv2.GaussianBlur(white, (0, 0), corr_px / step)
        field = field * np.float32(rms_px / max(float(field.std()), 1e-12))
        up = cv2.resize(field, (small[1] * step, small[0] * step), interpolation=cv2.INTER_CUBIC)
        out.append(up[:h, :w])
    return out[0], out[1]


def displacement_field(
    shape: tuple[int, int],
    rms_px: float,
    spectrum: str,
    corr_px: float,
    outer_px: float,
    rng: np.random.Generator,
) -> tuple[np.ndarray, np.ndarray]:
    """(dx, dy), each (H, W) float32 px: one frame's shimmer with the named spectrum
    (``SPECTRA``); ``corr_px`` is used by gaussian and fine, ``outer_px`` by vonkarman."""
    if spectrum == "gaussian":
        return shimmer_field(shape, rms_px, corr_px, rng)
    if spectrum == "fine":
        return fine_field(shape, rms_px, corr_px, rng)
    if spectrum == "vonkarman":
        return vonkarman_field(shape, rms_px, outer_px, rng)
    raise ValueError(f"unknown shimmer spectrum {spectrum!r}; one of {', '.join(SPECTRA)}")


def _scaled(field: np.ndarray, rms_px: float) -> np.ndarray:
    """``field`` (H, W) scaled so that its root mean square is ``rms_px`` (float32)."""
    rms = float(np.sqrt(np.mean(np.square(field, dtype=np.float64))))
    return (field * (rms_px / max(rms, 1e-12))).astype(np.float32)


def fine_field(
    shape: tuple[int, int], rms_px: float, corr_px: float, rng: np.random.Generator
) -> tuple[np.ndarray, np.ndarray]:
    """(dx, dy), each (H, W) float32 px, RMS ``rms_px``: equal variance correlated over
    ``corr_px`` and over ``corr_px / FINE_RATIO`` (Gaussian sigmas, px)."""
    part = rms_px / math.sqrt(2)
    coarse = shimmer_field(shape, part, corr_px, rng)
    fine = shimmer_field(shape, part, max(corr_px / FINE_RATIO, 0.5), rng)
    return _scaled(coarse[0] + fine[0], rms_px), _scaled(coarse[1] + fine[1], rms_px)


def vonkarman_psd(f: np.ndarray, outer_px: float) -> np.ndarray:
    """The von Karman spectrum's shape ``(f^2 + 1/L0^2)^(-11/6)`` at spatial frequencies
    ``f`` (cycles/px), unnormalised."""
    return (np.square(f) + outer_px**-2.0) ** (-11.0 / 6.0)


def vonkarman_grid(shape: tuple[int, int], outer_px: float) -> tuple[int, int]:
    """(n, step): the periodic synthesis grid for an image of ``shape`` (H, W) and outer
    scale ``outer_px``: n x n points ``step`` px apart, one period at least the image's
    larger side plus 4 outer scales."""
    span = max(shape) + 4 * outer_px
    step = max(1, min(math.ceil(span / GRID_MAX), int(outer_px / 128)))
    return sfft.next_fast_len(math.ceil(span / step), real=True), step


def vonkarman_periodic(
    n: int, step: int, outer_px: float, rng: np.random.Generator
) -> np.ndarray:
    """(n, n) float64: one periodic draw with the von Karman spectrum on a grid of
    points ``step`` px apart (white noise filtered by ``sqrt(W)``), unscaled."""
    fy = sfft.fftfreq(n, d=step)[:, None]
    fx = sfft.rfftfreq(n, d=step)[None, :]
    amplitude = np.sqrt(vonkarman_psd(np.hypot(fx, fy), outer_px))
    return sfft.irfft2(sfft.rfft2(rng.standard_normal((n, n))) * amplitude, s=(n, n))


def vonkarman_field(
    shape: tuple[int, int], rms_px: float, outer_px: float, rng: np.random.Generator
) -> tuple[np.ndarray, np.ndarray]:
    """(dx, dy), each (H, W) float32 px with RMS ``rms_px`` over the image: independent
    draws with the von Karman spectrum of outer scale ``outer_px`` (px)."""
    h, w = shape
    n, step = vonkarman_grid(shape, outer_px)
    small = (-(-h // step) + 1, -(-w // step) + 1)
    out = []
    for _ in range(2):
        field = vonkarman_periodic(n, step, outer_px, rng)[: small[0], : small[1]]
        up = cv2.resize(field.astype(np.float32), (small[1] * step, small[0] * step),
                        interpolation=cv2.INTER_CUBIC)
        out.append(_scaled(up[:h, :w], rms_px))
    return out[0], out[1]

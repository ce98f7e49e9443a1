"""Shimmer spectra: the default untouched, the others with the statistics designed."""

from __future__ import annotations

import cv2
import numpy as np
import pytest

from rigkit.synth.shimmer import (
    displacement_field,
    shimmer_field,
    vonkarman_field,
    vonkarman_grid,
    vonkarman_periodic,
    vonkarman_psd,
)

SHAPE = (240, 320)


def _ms(f: np.ndarray) -> float:
    return float(np.mean(np.square(f, dtype=np.float64)))


def test_gaussian_is_the_field_it_always_was() -> None:
    a = displacement_field(SHAPE, 0.3, "gaussian", 8.0, 1500.0, np.random.default_rng(4))
    b = shimmer_field(SHAPE, 0.3, 8.0, np.random.default_rng(4))
    assert all(np.array_equal(x, y) for x, y in zip(a, b, strict=True))


@pytest.mark.parametrize("spectrum", ["fine", "vonkarman"])
def test_every_frame_has_the_requested_rms_per_axis(spectrum) -> None:
    rng = np.random.default_rng(2)
    for _ in range(3):
        for f in displacement_field(SHAPE, 0.3, spectrum, 6.0, 1500.0, rng):
            assert f.shape == SHAPE and f.dtype == np.float32
            assert np.sqrt(_ms(f)) == pytest.approx(0.3, rel=1e-3)


def test_vonkarman_spectrum_is_the_power_law_with_its_outer_scale() -> None:
    # The periodic draw's periodogram, divided by the designed spectrum, is flat (white
    # noise filtered), and its log-log slope well above 1/L0 is the model's, -> -11/3.
    n, outer = 256, 64.0
    rng = np.random.default_rng(5)
    power = sum(np.abs(np.fft.fft2(vonkarman_periodic(n, 1, outer, rng))) ** 2
                for _ in range(6))
    f = np.hypot(*np.meshgrid(np.fft.fftfreq(n), np.fft.fftfreq(n)))
    edges = np.geomspace(2 / n, 0.5, 12)
    ring = np.digitize(f, edges)
    ratio = np.array([np.mean(power[ring == i] / vonkarman_psd(f[ring == i], outer))
                      for i in range(3, len(edges))])  # rings with enough samples
    assert ratio.max() / ratio.min() < 1.3
    far = (f > 0.12) & (f < 0.45)
    slope = np.polyfit(np.log(f[far]), np.log(power[far]), 1)[0]
    model = np.polyfit(np.log(f[far]), np.log(vonkarman_psd(f[far], outer)), 1)[0]
    assert slope == pytest.approx(model, abs=0.15) and model == pytest.approx(-11 / 3, abs=0.2)


def _low_share(field: np.ndarray, sigma: float) -> float:
    """Share of the field's mean square that a Gaussian low-pass of sigma px keeps."""
    return _ms(cv2.GaussianBlur(field, (0, 0), sigma)) / _ms(field)


def test_vonkarman_variance_split_is_as_designed() -> None:
    # What a Gaussian low-pass keeps, measured on frames, against the spectrum's sum
    # sum W |H|^2 / sum W over the synthesis grid (H the filter's transfer function).
    shape, outer, sigma = (256, 256), 100.0, 4.0
    n, step = vonkarman_grid(shape, outer)
    fx, fy = np.meshgrid(np.fft.fftfreq(n, d=step), np.fft.fftfreq(n, d=step))
    w = vonkarman_psd(np.hypot(fx, fy), outer)
    designed = np.sum(w * np.exp(-4 * np.pi**2 * sigma**2 * (fx**2 + fy**2))) / np.sum(w)
    rng = np.random.default_rng(8)
    kept = [_low_share(f, sigma) for _ in range(6) for f in vonkarman_field(shape, 0.3, outer, rng)]
    assert np.mean(kept) == pytest.approx(designed, abs=0.03)
    assert 0.6 < designed < 0.95  # a test that can tell


def test_vonkarman_is_mostly_large_scale_fine_is_mostly_small() -> None:
    # With L0 = 1500 px, (1 + (L0 / 100)^2)^(-5/6) = 1.1 % of the variance is at scales
    # under 100 px; the gaussian field (sigma 6.4 px, 1 % of 640 px) has most of it there.
    rng = np.random.default_rng(3)
    shape = (480, 640)

    def small_scale(spectrum: str, sigma: float) -> float:
        """Share of four frames' variance that a Gaussian high-pass of sigma px keeps."""
        fields = [f for _ in range(4)
                  for f in displacement_field(shape, 0.3, spectrum, 6.4, 1500.0, rng)]
        high = sum(_ms(f - cv2.GaussianBlur(f, (0, 0), sigma)) for f in fields)
        return high / sum(_ms(f) for f in fields)

    assert small_scale("vonkarman", 16.0) < 0.03
    assert small_scale("gaussian", 16.0) > 0.4
    assert small_scale("fine", 2.0) > 0.25 > 0.02 > small_scale("gaussian", 2.0)

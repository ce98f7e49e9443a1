"""rigkit.imagefile.rawio: RAW and plain-image frames -> grey, with real (generated) DNG files."""

from __future__ import annotations

import hashlib
from pathlib import Path

import cv2
import numpy as np
import pytest

from rigkit.errors import InputError
from rigkit.imagefile import rawio
from rigkit.imagefile.exif import read_exif
from rigkit.imagefile.rawio import decode_raw, is_raw, linear_grey, load_linear_grey, to_pipeline
from tests.dngutil import write_dng

H, W = 48, 64  # Bayer mosaic size (rows, columns)
WHITE = 4095  # 12-bit sensor
FULL = 65535.0
# Pixels this far from the border are away from demosaicing border effects.
M = 4

EXIF = {
    "make": "NIKON CORPORATION",
    "model": "NIKON Z 9",
    "datetime_original": "2024:05:17 06:41:09",
    "focal_length_mm": 600.0,
    "focal_length_35mm_mm": 600,
    "exposure_time_s": 1 / 1600,
    "f_number": 6.3,
    "iso": 400,
}


def _ramp(lo: float, hi: float) -> np.ndarray:
    """(H, W) uint16 neutral scene brightening left to right from lo to hi (raw units)."""
    row = np.linspace(lo, hi, W)
    return np.rint(np.tile(row, (H, 1))).astype(np.uint16)


def _sha256(path: Path) -> str:
    return hashlib.sha256(path.read_bytes()).hexdigest()


def _inner(img: np.ndarray) -> np.ndarray:
    return img[M:-M, M:-M]


# --- is_raw ---------------------------------------------------------------------------


def test_is_raw_by_suffix_any_case() -> None:
    for name in ("a.nef", "a.NEF", "b.Dng", "c.cr2", "d.CR3", "e.arw", "f.nrw", "g.RW2"):
        assert is_raw(name), name
    for name in ("a.png", "a.tif", "a.tiff", "a.jpg", "a", "nef", "a.nef.png"):
        assert not is_raw(name), name
    assert all(s == s.lower() and s.startswith(".") for s in rawio.RAW_SUFFIXES)


# --- decode_raw: a real DNG through LibRaw --------------------------------------------


def test_decode_is_linear_unbrightened_and_sensor_sized(tmp_path: Path) -> None:
    dark = write_dng(tmp_path / "dark.dng", _ramp(100, 900), white_level=WHITE)
    double = write_dng(tmp_path / "double.dng", _ramp(200, 1800), white_level=WHITE)
    rgb_dark, rgb_double = decode_raw(dark), decode_raw(double)

    # Sensor grid kept: no border crop, no rotation, 3 channels of 16 bits.
    assert rgb_dark.shape == (H, W, 3) and rgb_dark.dtype == np.uint16
    assert rgb_double.shape == (H, W, 3)
    # No auto-brightening: raw/white maps straight to value/65535 (neutral scene,
    # identity colour matrix, neutral white balance), so the dark frame stays dark.
    expected = _ramp(100, 900)[..., None] / WHITE * FULL
    np.testing.assert_allclose(_inner(rgb_dark), _inner(expected).repeat(3, -1), rtol=0.03)
    assert rgb_dark.max() < 0.25 * FULL
    # Linear: twice the light, twice the value.
    ratio = _inner(rgb_double).astype(float) / _inner(rgb_dark)
    np.testing.assert_allclose(ratio, 2.0, rtol=0.03)


def test_black_level_is_subtracted(tmp_path: Path) -> None:
    bayer = (_ramp(0, 1000) + 512).astype(np.uint16)
    path = write_dng(tmp_path / "black.dng", bayer, black_level=512, white_level=WHITE)
    grey = linear_grey(decode_raw(path))
    expected = _ramp(0, 1000) / (WHITE - 512)
    np.testing.assert_allclose(_inner(grey), _inner(expected), atol=0.005)


def test_camera_white_balance_makes_neutral_grey(tmp_path: Path) -> None:
    # A grey surface under a warm light: red at half and blue at 0.7 of green on the
    # sensor, and the camera recorded that as its neutral.
    bayer = np.full((H, W), 2000, np.uint16)
    bayer[0::2, 0::2] = 1000  # R of RGGB
    bayer[1::2, 1::2] = 1400  # B
    # A camera-like colour matrix: LibRaw normalises it so neutral stays neutral.
    matrix = (0.9, -0.3, -0.05, -0.4, 1.2, 0.2, -0.05, 0.15, 0.6)
    path = write_dng(
        tmp_path / "wb.dng", bayer, as_shot_neutral=(0.5, 1.0, 0.7), color_matrix=matrix
    )
    means = _inner(decode_raw(path)).reshape(-1, 3).mean(0)
    np.testing.assert_allclose(means, 2000 / WHITE * FULL, rtol=0.02)


def test_bright_square_stays_where_it_is(tmp_path: Path) -> None:
    bayer = np.full((H, W), 200, np.uint16)
    rows, cols = slice(10, 20), slice(36, 52)  # off-centre, so flips would move it
    bayer[rows, cols] = 3000
    path = write_dng(tmp_path / "square.dng", bayer, pattern="GRBG")
    grey = linear_grey(decode_raw(path))
    assert grey.shape == (H, W) and grey.dtype == np.float32
    ys, xs = np.nonzero(grey > (200 + 3000) / 2 / WHITE)
    assert (ys.min(), ys.max(), xs.min(), xs.max()) == (10, 19, 36, 51)
    assert grey[rows, cols].mean() == pytest.approx(3000 / WHITE, rel=0.03)
    assert np.median(grey) == pytest.approx(200 / WHITE, rel=0.03)


def test_orientation_tag_is_not_applied(tmp_path: Path) -> None:
    bayer = np.full((H, W), 200, np.uint16)
    bayer[:8, :8] = 3000  # bright top-left corner
    path = write_dng(tmp_path / "portrait.dng", bayer, orientation=6)  # "rotate 90 CW"
    grey = linear_grey(decode_raw(path))
    assert grey.shape == (H, W)
    assert grey[2, 2] > 0.5 and grey[-3, -3] < 0.1 and grey[2, -3] < 0.1


def test_exif_of_generated_dng(tmp_path: Path) -> None:
    path = write_dng(tmp_path / "exif.dng", _ramp(0, 4000), exif=EXIF)
    info = read_exif(path)
    assert info.make == EXIF["make"] and info.model == EXIF["model"]
    assert info.datetime_original == EXIF["datetime_original"]
    assert info.focal_length_mm == pytest.approx(600.0)
    assert info.focal_length_35mm_mm == pytest.approx(600.0)
    assert info.exposure_time_s == pytest.approx(1 / 1600)
    assert info.f_number == pytest.approx(6.3)
    assert info.iso == pytest.approx(400)
    # ...and LibRaw still decodes the file with its EXIF IFD appended.
    assert decode_raw(path).shape == (H, W, 3)


# --- linear_grey ----------------------------------------------------------------------


def test_linear_grey_uses_rec709_weights() -> None:
    rgb = np.zeros((2, 3, 3), np.uint16)
    rgb[0, 0] = (65535, 0, 0)
    rgb[0, 1] = (0, 65535, 0)
    rgb[0, 2] = (0, 0, 65535)
    rgb[1, :] = (32768, 32768, 32768)
    grey = linear_grey(rgb)
    assert grey.shape == (2, 3) and grey.dtype == np.float32
    np.testing.assert_allclose(grey[0], (0.2126, 0.7152, 0.0722), atol=1e-6)
    np.testing.assert_allclose(grey[1], 32768 / FULL, atol=1e-6)
    assert linear_grey(np.full((1, 1, 3), 65535, np.uint16))[0, 0] == pytest.approx(1.0)
    with pytest.raises(ValueError):
        linear_grey(np.zeros((2, 3, 3), np.uint8))


# --- load_linear_grey: RAW and its cache ----------------------------------------------


def test_raw_is_loaded_linear(tmp_path: Path) -> None:
    path = write_dng(tmp_path / "frame.dng", _ramp(100, 900))
    grey = load_linear_grey(path)
    assert grey.shape == (H, W) and grey.dtype == np.float32
    np.testing.assert_allclose(_inner(grey), _inner(_ramp(100, 900)) / WHITE, rtol=0.03)


def test_cache_is_written_once_and_read_back(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    capture, cache_dir = tmp_path / "capture", tmp_path / "cache"
    capture.mkdir()
    path = write_dng(capture / "left.dng", _ramp(100, 3000), exif=EXIF)
    sha = _sha256(path)

    first = load_linear_grey(path, cache_dir, sha)

    assert [p.name for p in cache_dir.iterdir()] == [f"{sha[:16]}.linear.png"]  # no temp left
    assert [p.name for p in capture.iterdir()] == ["left.dng"]  # nothing next to the RAW
    assert _sha256(path) == sha  # input untouched

    def no_decoding(*_args: object) -> np.ndarray:
        raise AssertionError("decoded again instead of reading the cache")

    monkeypatch.setattr(rawio, "decode_raw", no_decoding)
    second = load_linear_grey(path, cache_dir, sha)
    assert second.dtype == np.float32
    np.testing.assert_array_equal(second, first)  # same values, cached or not
    # A different hash is a different file: not served from this cache.
    with pytest.raises(AssertionError, match="decoded again"):
        load_linear_grey(path, cache_dir, "0" * 64)


def test_damaged_cache_is_decoded_again_and_replaced(tmp_path: Path) -> None:
    path = write_dng(tmp_path / "left.dng", _ramp(100, 3000))
    sha, cache_dir = _sha256(path), tmp_path / "cache"
    cache_dir.mkdir()
    cache = cache_dir / f"{sha[:16]}.linear.png"
    cache.write_bytes(b"not a png")
    grey = load_linear_grey(path, cache_dir, sha)
    np.testing.assert_allclose(_inner(grey), _inner(_ramp(100, 3000)) / WHITE, rtol=0.03)
    reread = cv2.imread(str(cache), cv2.IMREAD_UNCHANGED)
    assert reread is not None and reread.dtype == np.uint16 and reread.shape == (H, W)


def test_without_cache_nothing_is_written(tmp_path: Path) -> None:
    path = write_dng(tmp_path / "left.dng", _ramp(100, 3000))
    load_linear_grey(path, None, _sha256(path))
    load_linear_grey(path, tmp_path / "cache", None)
    assert [p.name for p in tmp_path.iterdir()] == ["left.dng"]


# --- errors ---------------------------------------------------------------------------


def _assert_input_error(path: Path) -> None:
    for load in (decode_raw, load_linear_grey):
        with pytest.raises(InputError) as info:
            load(path)
        message = str(info.value)
        assert str(path) in message and "\n" not in message, message


def test_garbage_with_raw_suffix_is_an_input_error(tmp_path: Path) -> None:
    rng = np.random.default_rng(0)
    for name in ("noise.nef", "noise.dng", "empty.cr2"):
        path = tmp_path / name
        path.write_bytes(b"" if name.startswith("empty") else rng.bytes(5000))
        _assert_input_error(path)


def test_truncated_dng_is_an_input_error(tmp_path: Path) -> None:
    good = write_dng(tmp_path / "good.dng", _ramp(0, 4000), exif=EXIF)
    data = good.read_bytes()
    for name, size in (("half.dng", len(data) // 2), ("header.nef", 100)):
        cut = tmp_path / name
        cut.write_bytes(data[:size])
        _assert_input_error(cut)


def test_missing_file_is_an_input_error(tmp_path: Path) -> None:
    _assert_input_error(tmp_path / "missing.dng")
    with pytest.raises(InputError, match="missing.png"):
        load_linear_grey(tmp_path / "missing.png")
    folder = tmp_path / "folder.nef"
    folder.mkdir()
    _assert_input_error(folder)


# --- plain images ---------------------------------------------------------------------


def test_png_8_and_16_bit_are_read_unlinearised(tmp_path: Path) -> None:
    grey8 = np.tile(np.arange(0, 256, 4, dtype=np.uint8), (H, 1))
    grey16 = grey8.astype(np.uint16) * 257
    colour8 = np.dstack([grey8] * 3)
    for name, img in (("g8.png", grey8), ("g16.png", grey16), ("c8.png", colour8)):
        path = tmp_path / name
        assert cv2.imwrite(str(path), img)
        loaded = load_linear_grey(path, tmp_path / "cache", "a" * 64)
        assert loaded.shape == (H, W) and loaded.dtype == np.float32, name
        np.testing.assert_allclose(loaded, grey8 / 255.0, atol=1e-6, err_msg=name)
    assert not (tmp_path / "cache").exists()  # only RAW frames are cached


def test_jpeg_orientation_tag_is_not_applied(tmp_path: Path) -> None:
    from PIL import Image

    rng = np.random.default_rng(0)
    img = (30 + 20 * rng.random((H, W))).astype(np.uint8)  # dim texture: a picture
    img[:8, :8] = 250  # bright top-left corner
    exif = Image.Exif()
    exif[274] = 6  # Orientation: "rotate 90 CW"; OpenCV applies it unless told not to
    path = tmp_path / "portrait.jpg"
    Image.fromarray(img).save(path, exif=exif.tobytes(), quality=95)
    grey = load_linear_grey(path)
    assert grey.shape == (H, W)
    assert grey[2, 2] > 0.8 and grey[2, -3] < 0.3


def test_unreadable_png_is_an_input_error(tmp_path: Path) -> None:
    path = tmp_path / "broken.png"
    path.write_bytes(b"\x89PNG but not really")
    with pytest.raises(InputError, match="broken.png"):
        load_linear_grey(path)


# --- to_pipeline ----------------------------------------------------------------------


def test_to_pipeline_linear_uses_one_scale_for_all_frames() -> None:
    rng = np.random.default_rng(1)
    base = rng.uniform(0.01, 0.2, (H, W)).astype(np.float32)
    dim, bright = base, 2 * base
    out_dim, out_bright = to_pipeline([dim, bright], linear=True)
    for out in (out_dim, out_bright):
        assert out.shape == (H, W) and out.dtype == np.float32
        assert out.min() >= 0.0 and out.max() <= 255.0
    assert np.all(out_bright > out_dim)  # brighter frame stays brighter, pixel by pixel
    # The brightest frame fills the range; the other is not stretched on its own.
    assert np.percentile(out_bright, 99.9) == pytest.approx(255.0, abs=1.0)
    assert np.percentile(out_dim, 99.9) < 0.8 * 255
    (alone,) = to_pipeline([dim], linear=True)
    assert np.percentile(alone, 99.9) == pytest.approx(255.0, abs=1.0)


def test_to_pipeline_linear_keeps_shadow_levels() -> None:
    # A dim linear frame (up to 5 % of full scale) with a dark half: as plain 8-bit
    # linear data its dark half would get about 6 levels.
    ramp = np.linspace(0.0, 0.05, 4096, dtype=np.float32).reshape(64, 64)
    (out,) = to_pipeline([ramp], linear=True)
    dark_levels = np.unique(out[ramp < 0.025].astype(np.uint8))
    assert len(dark_levels) > 150
    assert np.all(np.diff(out.ravel()) >= 0)  # monotonic


def test_to_pipeline_plain_is_times_255() -> None:
    frame = np.linspace(0.0, 1.0, H * W, dtype=np.float32).reshape(H, W)
    (out,) = to_pipeline([frame], linear=False)
    assert out.dtype == np.float32
    np.testing.assert_allclose(out, frame * 255.0, atol=1e-4)


def test_to_pipeline_black_frames_do_not_divide_by_zero() -> None:
    outs = to_pipeline([np.zeros((4, 4), np.float32)] * 3, linear=True)
    assert all(np.all(out == 0.0) for out in outs)

"""Loading a capture: frames decoded ahead in worker threads, judged in their order."""

from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np
import pytest

from rigkit.capture.frames import FrameFile, load_capture
from rigkit.errors import InputError
from rigkit.imagefile.rawio import load_linear_grey, to_pipeline
from rigkit.pipeline.burst import stack_burst


def _frames(folder: Path, rng: np.random.Generator, n: int, size=(96, 64)) -> list[Path]:
    """``n`` 16-bit PNGs of one textured view, each moved by a fraction of a pixel."""
    base = cv2.GaussianBlur(rng.uniform(0, 65535, (size[1] + 8, size[0] + 8)), (0, 0), 1.5)
    paths = []
    for i in range(n):
        shift = np.float64([[1, 0, rng.uniform(-0.5, 0.5)], [0, 1, rng.uniform(-0.5, 0.5)]])
        moved = cv2.warpAffine(base, shift, (base.shape[1], base.shape[0]))[4:-4, 4:-4]
        path = folder / f"{folder.name}-{i}.png"
        cv2.imwrite(str(path), np.clip(moved, 0, 65535).astype(np.uint16))
        paths.append(path)
    return paths


@pytest.fixture
def capture(tmp_path: Path) -> dict[str, list[Path]]:
    rng = np.random.default_rng(3)
    bursts = {}
    for position in ("left", "right", "back"):
        (tmp_path / position).mkdir()
        bursts[position] = _frames(tmp_path / position, rng, 3)
    return bursts


def _files(bursts: dict[str, list[Path]]) -> dict[str, tuple[FrameFile, ...]]:
    return {pos: tuple(FrameFile(p) for p in paths) for pos, paths in bursts.items()}


def test_decoding_ahead_gives_what_one_frame_at_a_time_gives(capture) -> None:
    loaded = load_capture(_files(capture))
    one_by_one = to_pipeline([stack_burst([load_linear_grey(p) for p in capture[pos]], pos)
                              for pos in ("left", "right", "back")], linear=False)
    for got, want in zip(loaded.images, one_by_one, strict=True):
        np.testing.assert_array_equal(got, want)
    assert loaded.size == (96, 64)


def test_the_first_problem_in_frame_order_is_named(capture) -> None:
    # The back burst is decoded while the left one is judged: its missing frame must not
    # hide the left burst's cut-short frame, and a later frame of another size is named
    # against the first frame's size.
    data = capture["left"][1].read_bytes()
    capture["left"][1].write_bytes(data[: len(data) // 2])
    capture["back"][2].unlink()
    with pytest.raises(InputError, match=r"left-1\.png"):
        load_capture(_files(capture))
    capture["left"][1].write_bytes(data)
    with pytest.raises(InputError, match=r"back-2\.png: no such file"):
        load_capture(_files(capture))
    small = cv2.imread(str(capture["right"][0]), cv2.IMREAD_UNCHANGED)[:-2]
    cv2.imwrite(str(capture["back"][2]), small)
    with pytest.raises(InputError, match=r"back-2\.png: 96x62 px, but the left frame "
                                         r".*left-0\.png is 96x64 px"):
        load_capture(_files(capture))

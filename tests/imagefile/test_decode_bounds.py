"""Image decoding fails closed and bounded (issue 36): a header the size check cannot
read refuses the file before any decoder sees it, and no file name reaches OpenCV or
LibRaw as a C string (a byte 0xff in a path crashed OpenCV's imread)."""

from __future__ import annotations

import os
import struct
import zlib
from collections.abc import Callable
from pathlib import Path

import cv2
import numpy as np
import pytest
import tifffile

from rigkit.errors import InputError
from rigkit.export.source import file_depth
from rigkit.imagefile.decode import load_grey
from rigkit.imagefile.imagesize import header_size
from rigkit.imagefile.rawio import decode_raw, frame_size, load_linear_grey
from tests.conftest import make_record
from tests.dngutil import bayer_from_grey, write_dng
from tests.export.helpers import depth_plane

_FF = os.fsdecode(b"\xff")
"""A name holding the byte 0xff: on Linux Python makes it the lone surrogate U+DCFF."""


def _never(*_args: object, **_kwargs: object) -> None:
    raise AssertionError("the decoder was called")


@pytest.fixture
def no_decoding(monkeypatch: pytest.MonkeyPatch) -> None:
    """Any call of OpenCV's decoders fails the test."""
    monkeypatch.setattr(cv2, "imread", _never)
    monkeypatch.setattr(cv2, "imdecode", _never)


@pytest.fixture
def no_imread(monkeypatch: pytest.MonkeyPatch) -> None:
    """cv2.imread (a str path handed to C) fails the test instead of crashing it."""
    monkeypatch.setattr(cv2, "imread", _never)


def _picture(height: int, width: int) -> np.ndarray:
    """(H, W) uint8 smooth waves: a picture to rigkit's eye, not noise."""
    y, x = np.mgrid[:height, :width]
    return np.rint(128 + 90 * np.sin(x / 6.0) * np.cos(y / 9.0)).astype(np.uint8)


def _refused(path: Path, match: str) -> None:
    """Both ways a session reads an ordinary frame refuse ``path`` with one line naming it."""
    reads: tuple[Callable[[Path], object], ...] = (load_linear_grey, frame_size)
    for read in reads:
        with pytest.raises(InputError, match=match) as caught:
            read(path)
        assert str(path) in str(caught.value)
        assert "\n" not in str(caught.value)


# --------------------------------------------------------------------------- hostile headers


def _ifd_entries(order: str, entries: list[tuple[int, int, int]], big: bool) -> bytes:
    """TIFF directory entries (tag, type, value), one value each, packed in place."""
    form = order + ("HHQQ" if big else "HHII")
    return b"".join(struct.pack(form, tag, kind, 1, value) for tag, kind, value in entries)


def _strip_tags(width: int, height: int, data_at: int) -> list[tuple[int, int, int]]:
    """Width, height and one uncompressed 8-bit grey strip of 16 bytes at ``data_at``."""
    return [(256, 4, width), (257, 4, height), (258, 3, 8), (259, 3, 1), (262, 3, 1),
            (273, 4, data_at), (277, 3, 1), (278, 4, height), (279, 4, 16)]


def test_a_bigtiff_declaring_a_huge_size_is_refused_unread(tmp_path: Path,
                                                           no_decoding: None) -> None:
    # Before: the BigTIFF header went unread, and the file was decoded at 2.45 GB.
    path = tmp_path / "big.tif"
    tags = _strip_tags(32000, 32000, data_at=16)
    ifd = struct.pack("<Q", len(tags)) + _ifd_entries("<", tags, big=True) + bytes(8)
    path.write_bytes(struct.pack("<2sHHHQ", b"II", 43, 8, 0, 32) + bytes(16) + ifd)
    _refused(path, r"32000x32000 px .* beyond the 250 MP")


def test_a_small_bigtiff_reads_as_a_tiff(tmp_path: Path) -> None:
    img = _picture(48, 64)
    big, classic = tmp_path / "big.tif", tmp_path / "classic.tif"
    tifffile.imwrite(big, img, bigtiff=True)
    tifffile.imwrite(classic, img)
    assert header_size(big, big.read_bytes()) == (64, 48)
    assert np.array_equal(load_linear_grey(big, expected=(64, 48)), load_linear_grey(classic))


def test_a_tiff_whose_first_directory_is_too_long_is_refused_unread(
        tmp_path: Path, no_decoding: None) -> None:
    # Before: width and height came after the 1000 entries read, and the file was decoded.
    path = tmp_path / "long.tif"
    dummies = [(40000 + i, 3, 0) for i in range(1100)]
    tags = dummies + _strip_tags(30000, 30000, data_at=8)
    ifd = struct.pack("<H", len(tags)) + _ifd_entries("<", tags, big=False) + bytes(4)
    path.write_bytes(struct.pack("<2sHI", b"II", 42, 24) + bytes(16) + ifd)
    _refused(path, r"TIFF header .* first directory of 1,109 entries")


def test_a_camera_raw_under_an_ordinary_images_name_is_refused_unread(
        tmp_path: Path, no_decoding: None) -> None:
    """A DNG, a NEF-like TIFF whose first image is a reduced-resolution preview, and a
    CR2, each named .tif or .png: read as TIFFs they gave their preview (1888x1182 for
    a 5472x3648 DNG) for the frame; now each is refused with the name to give it."""
    dng = tmp_path / "shot.dng"
    write_dng(dng, bayer_from_grey(_picture(48, 64)))
    for name in ("shot.tif", "shot.png"):
        renamed = tmp_path / name
        renamed.write_bytes(dng.read_bytes())
        _refused(renamed, r"TIFF header is a DNG's \(a camera RAW\): give the file its .dng")
    preview = tmp_path / "preview.tif"
    tags = [(254, 4, 1), *_strip_tags(16, 1, data_at=8)]
    ifd = struct.pack("<H", len(tags)) + _ifd_entries("<", tags, big=False) + bytes(4)
    preview.write_bytes(struct.pack("<2sHI", b"II", 42, 24) + bytes(16) + ifd)
    _refused(preview, r"reduced-resolution preview first \(a camera RAW's\?\)")
    cr2 = tmp_path / "canon.tif"
    cr2.write_bytes(struct.pack("<2sHI", b"II", 42, 16) + b"CR\x02\x00" + bytes(4)
                    + struct.pack("<H", 0) + bytes(4))
    _refused(cr2, r"TIFF header is a Canon CR2's")


def _jpeg(img: np.ndarray, fill: int, size: tuple[int, int] | None = None) -> bytes:
    """``img`` as a baseline JPEG with ``fill`` bytes 0xff before its SOF marker and, where
    given, another (width, height) written into the SOF."""
    data = bytearray(cv2.imencode(".jpg", img)[1].tobytes())
    sof = data.index(b"\xff\xc0")
    if size is not None:
        data[sof + 5:sof + 9] = struct.pack(">HH", size[1], size[0])
    return bytes(data[:sof] + b"\xff" * fill + data[sof:])


def test_a_jpeg_with_a_fill_byte_before_a_huge_sof_is_refused_unread(
        tmp_path: Path, no_decoding: None) -> None:
    # Before: the fill byte stopped the header parser, and the file was decoded at 2.1 GB.
    path = tmp_path / "fill.jpg"
    path.write_bytes(_jpeg(_picture(48, 64), fill=1, size=(40000, 40000)))
    _refused(path, r"40000x40000 px .* beyond the 250 MP")


def test_a_jpeg_with_fill_bytes_reads_as_without(tmp_path: Path) -> None:
    img = _picture(48, 64)
    plain, filled = tmp_path / "plain.jpg", tmp_path / "filled.jpg"
    plain.write_bytes(_jpeg(img, fill=0))
    filled.write_bytes(_jpeg(img, fill=3))
    assert header_size(filled, filled.read_bytes()) == (64, 48)
    grey = load_linear_grey(filled, expected=(64, 48))
    assert np.array_equal(grey, load_linear_grey(plain))


@pytest.mark.parametrize("head", [b"BM" + bytes(60), b"II+\x00" + bytes(60), b""],
                         ids=["bmp", "damaged-bigtiff", "empty"])
def test_a_header_that_cannot_be_read_is_refused_unread(tmp_path: Path, head: bytes,
                                                        no_decoding: None) -> None:
    # A BMP (a format the size check does not read), a damaged BigTIFF, an empty file.
    path = tmp_path / "frame.png"
    path.write_bytes(head)
    _refused(path, "refused unread")


def test_what_opencv_refuses_is_an_input_error_not_a_traceback(tmp_path: Path) -> None:
    # Before: load_grey let OpenCV's exception for 40000x40000 px (over its own limit) out.
    path = tmp_path / "huge.png"
    data = bytearray(cv2.imencode(".png", _picture(24, 32))[1].tobytes())
    data[16:24] = struct.pack(">II", 40000, 40000)
    data[29:33] = struct.pack(">I", zlib.crc32(data[12:29]))  # the IHDR chunk's CRC
    path.write_bytes(bytes(data))
    with pytest.raises(InputError, match="huge.png: not a readable image .*OpenCV refuses it"):
        load_grey(path)


# --------------------------------------------------------------------------- byte 0xff in a path


def test_a_png_whose_name_holds_the_byte_0xff_is_read(tmp_path: Path, no_imread: None) -> None:
    # Before: OpenCV's imread died of SIGSEGV on the surrogate, with no message.
    img = _picture(24, 32)
    path = tmp_path / f"{_FF}.png"
    path.write_bytes(cv2.imencode(".png", img)[1].tobytes())
    assert np.array_equal(load_grey(path), img.astype(np.float32))


def test_a_raw_frame_under_a_folder_named_with_0xff_is_read_and_cached(
        tmp_path: Path, no_imread: None) -> None:
    # Before: rawpy refused the str path with a UnicodeEncodeError traceback.
    bayer = bayer_from_grey(_picture(48, 64).astype(np.float32) / 255)
    card = tmp_path / _FF
    card.mkdir()
    path, plain = write_dng(card / "a.dng", bayer), write_dng(tmp_path / "a.dng", bayer)
    assert np.array_equal(decode_raw(path), decode_raw(plain))
    assert frame_size(path) == (64, 48)
    sha = "ff" * 32
    first = load_linear_grey(path, card / "cache", sha)
    assert np.array_equal(load_linear_grey(path, card / "cache", sha), first)  # from the cache
    assert list((card / "cache").iterdir())


def test_a_depth_maps_grey_under_a_folder_named_with_0xff_is_read(tmp_path: Path,
                                                                   no_imread: None) -> None:
    folder = tmp_path / _FF
    folder.mkdir()
    depth = depth_plane()
    np.save(folder / "d.npy", depth)
    np.save(folder / "d.sigma.npy", depth * np.float32(0.01))
    (folder / "d.grey.png").write_bytes(
        cv2.imencode(".png", np.full(depth.shape, 77, np.uint8))[1].tobytes())
    (folder / "d.json").write_text(make_record(image_size_px=depth.shape[::-1]).to_json())
    assert set(np.unique(file_depth(folder / "d.npy").grey)) == {77}


def test_opencv_itself_refuses_beyond_the_largest_frame() -> None:
    """The decoders' own limit (read by OpenCV at its first import) is rigkit's."""
    import os

    import rigkit  # noqa: F401  (sets it before cv2 is first imported)
    from rigkit.imagefile.imagesize import MAX_FRAME_PIXELS

    assert int(os.environ["OPENCV_IO_MAX_IMAGE_PIXELS"]) == MAX_FRAME_PIXELS

"""Frames as cameras write them: the genuine files in ../shared/data/real-raw (skipped
where absent) and camera-style DNGs written here (a preview in IFD 0, the raw image in a
SubIFD). Each test is a row of issue 21's table: what a user does with a real file."""

from __future__ import annotations

import os
import shutil
from pathlib import Path

import cv2
import numpy as np
import pytest

from rigkit.capture import add_frame, create_session, frame_problems, load_session
from rigkit.cli import main
from rigkit.errors import InputError
from rigkit.imagefile.exif import read_exif
from rigkit.imagefile.picture import picture_problem
from rigkit.imagefile.rawio import frame_size, load_linear_grey
from tests.conftest import rig_file
from tests.dngutil import bayer_from_grey, write_camera_dng

REAL = Path(os.environ.get(
    "RIGKIT_REAL_RAW", Path(__file__).resolve().parents[3] / "shared" / "data" / "real-raw"))
"""The genuine camera files: ../shared/data/real-raw beside the checkout, or $RIGKIT_REAL_RAW."""


def real(name: str) -> Path:
    """A file of ../shared/data/real-raw; the test is skipped where it is absent."""
    path = REAL / name
    if not path.is_file():
        pytest.skip(f"{path} is not here")
    return path


def texture(size: tuple[int, int], seed: int = 0) -> np.ndarray:
    """(H, W) float in [0, 255]: smoothed noise, a scene with texture everywhere."""
    rng = np.random.default_rng(seed)
    noise = cv2.GaussianBlur(rng.random((size[1], size[0])), (0, 0), 2.0)
    return cv2.normalize(noise, None, 0, 255, cv2.NORM_MINMAX)


def camera_dng(path: Path, size: tuple[int, int] = (320, 240), seed: int = 0, **kw) -> Path:
    return write_camera_dng(path, bayer_from_grey(texture(size, seed)), **kw)


def raw_files(session_path: Path) -> list[str]:
    return sorted(p.name for p in (session_path / "raw").iterdir())


# --------------------------------------------------------------------------- sizes


def test_a_camera_style_dng_is_decoded_at_full_size_not_its_preview(tmp_path: Path) -> None:
    path = camera_dng(tmp_path / "a.dng", (320, 240))
    assert cv2.imread(str(path)).shape[:2] == (120, 160)  # what OpenCV takes for the image
    assert load_linear_grey(path).shape == (240, 320)
    assert frame_size(path) == (320, 240)


def test_add_frame_records_the_decoded_size_of_a_camera_style_dng(tmp_path: Path) -> None:
    session = create_session(tmp_path / "s", rig_file(tmp_path, (320, 240)))
    session = add_frame(session, "left", camera_dng(tmp_path / "a.dng"))
    assert session.frames["left"].size_px == (320, 240)


def test_rig_check_quotes_the_decoded_size_of_real_files(tmp_path: Path, capsys) -> None:
    # tinydng: raw 1888x1182, decoded 1734x1156; the D70 NEF's IFD 0 is a 160x106 preview.
    dng, nef = real("tinydng_colorchart.dng"), real("exiftool_Nikon.nef")
    rig = rig_file(tmp_path, (1734, 1156))
    assert main(["rig", "check", str(rig), "--capture", str(dng), str(dng), str(nef)]) == 1
    out = capsys.readouterr().out.replace("\n", " ")
    assert "1888x1182" not in out and "160x106" not in out
    assert "back frame (exiftool_Nikon.nef): decoded image 3039x2014 px differs" in out


# --------------------------------------------------------------------------- EXIF


@pytest.mark.parametrize(
    "name, model, focal_mm, exposure_s, iso, taken",
    [
        ("exiftool_CanonRaw.cr3", "Canon EOS M50", 15.0, 1 / 80, 12800, "2018:02:21 12:08:56"),
        ("filetype_fixture.cr3", "Canon EOS R", 105.0, 1 / 125, 100, "2019:12:05 13:32:49"),
        ("exiftool_Panasonic.rw2", "DMC-LX3", 5.1, 1 / 250, 80, "2008:08:06 15:21:56"),
        ("exiftool_FujiFilm.raf", "FinePix S5Pro", 70.0, 1 / 250, 100, "2007:05:22 13:58:30"),
        ("exiftool_Minolta.mrw", "DiMAGE A2", 7.203125, 0.2, 64, "2004:11:18 23:14:58"),
    ],
)
def test_exif_from_containers_exifread_cannot_open(name, model, focal_mm, exposure_s, iso,
                                                   taken) -> None:
    info = read_exif(real(name))
    assert info.model == model and info.datetime_original == taken
    assert info.focal_length_mm == pytest.approx(focal_mm)
    assert info.exposure_time_s == pytest.approx(exposure_s)
    assert info.iso == iso


def test_iso_kept_only_in_nikons_maker_note(tmp_path: Path) -> None:
    # The D70's EXIF ISO tag (0x8827) renamed to an unknown one: ISO is left only in the
    # maker note's ISOSetting, as in files from cameras that write it only there.
    data = bytearray(real("exiftool_Nikon.nef").read_bytes())
    entry = bytes.fromhex("27880300")  # little-endian: tag 0x8827, type SHORT
    assert data.count(entry) == 1
    at = data.index(entry)
    data[at : at + 2] = bytes.fromhex("2888")
    path = tmp_path / "no-exif-iso.nef"
    path.write_bytes(bytes(data))
    assert read_exif(path).iso == 200


def test_panasonic_iso_from_its_raw_ifd(tmp_path: Path) -> None:
    # No EXIF ISO and no embedded JPEG: the PanasonicRaw IFD 0 tag 0x0017 still has it.
    data = bytearray(real("exiftool_Panasonic.rw2").read_bytes())
    data = data.replace(b"\xff\xd8\xff\xe1", b"\x00\xd8\xff\xe1")  # hide the embedded JPEG
    path = tmp_path / "no-jpeg.rw2"
    path.write_bytes(bytes(data))
    info = read_exif(path)
    assert info.iso == 80 and info.focal_length_35mm_mm is None


# --------------------------------------------------------------------------- no picture


REFUSED_REAL = [
    ("exiftool_DNG.dng", "image data is missing"),  # stripped: decodes to zeros
    ("exiv2_IMG_1361.dng", "image data is missing"),  # iPhone, stripped
    ("exiftool_Panasonic.rw2", "image data is missing"),  # 12 KB: decodes to a pattern
    ("imageio_Nikon_uncompressed.nef", "clipped white"),  # film scanner: white
    ("filetype_sony-zv-e10.arw", "cut short"),  # first 100 KB of a real file
    ("filetype_fixture.nef", "cut short"),  # a header only
]


@pytest.mark.parametrize("name, reason", REFUSED_REAL)
def test_real_files_without_a_picture_never_enter_raw(tmp_path: Path, capfd, name: str,
                                                      reason: str) -> None:
    source = real(name)
    try:  # a rig for the frame's own size, so the frame is refused for what it holds
        size = frame_size(source)
    except InputError:
        size = (320, 240)
    session = create_session(tmp_path / "s", rig_file(tmp_path, size))
    code = main(["session", "add-frame", str(session.path), "--position", "left", str(source)])
    err = capfd.readouterr().err.strip()
    assert code == 2 and reason in err
    assert len(err.splitlines()) == 1  # LibRaw's own messages do not reach the user
    assert err.startswith("rigkit session: error:") and name in err
    assert raw_files(session.path) == [] and not list((session.path / ".staging").iterdir())
    assert "no left frame" in frame_problems(load_session(session.path))


def test_a_real_dng_cut_short_is_refused(tmp_path: Path) -> None:
    # A card pulled mid-copy: the lossy 6D DNG at 95 % decodes with a grey block, and
    # LibRaw says "Premature end of JPEG file"; the 14-bit one fails outright.
    for name in ("photoprism_canon_eos_6d.dng", "tinydng_colorchart.dng"):
        data = real(name).read_bytes()
        cut = tmp_path / name
        cut.write_bytes(data[: int(0.95 * len(data))])
        with pytest.raises(InputError, match="cut short"):
            load_linear_grey(cut)


def test_real_photographs_are_accepted_dark_as_they_are() -> None:
    # The 6D frame is dark (median 1 % of full scale); the colour chart is low in contrast.
    for name in ("photoprism_canon_eos_6d.dng", "tinydng_colorchart.dng"):
        assert picture_problem(load_linear_grey(real(name))) is None


@pytest.mark.parametrize(
    "make, reason",
    [
        (lambda g: np.zeros_like(g), "blank"),
        (lambda g: np.full_like(g, 4095), "clipped white"),
        (lambda g: np.random.default_rng(1).integers(0, 4096, g.shape).astype(np.uint16),
         "noise with no picture"),
    ],
)
def test_camera_style_dngs_without_a_picture_are_refused(tmp_path: Path, make, reason) -> None:
    bayer = make(bayer_from_grey(texture((320, 240))))
    path = write_camera_dng(tmp_path / "x.dng", bayer)
    session = create_session(tmp_path / "s", rig_file(tmp_path, (320, 240)))
    with pytest.raises(InputError, match=reason):
        add_frame(session, "left", path)
    assert raw_files(session.path) == []


def test_a_jpeg_cut_short_is_refused(tmp_path: Path, capfd) -> None:
    full = tmp_path / "full.jpg"
    cv2.imwrite(str(full), texture((320, 240)).astype(np.uint8))
    cut = tmp_path / "cut.jpg"
    cut.write_bytes(full.read_bytes()[: int(0.6 * full.stat().st_size)])
    with pytest.raises(InputError, match="cut short or damaged .*Premature end of JPEG"):
        load_linear_grey(cut)
    assert capfd.readouterr().err == ""  # libjpeg's complaint was read, not printed


def test_a_complaint_is_quoted_without_opencvs_log_prefix(tmp_path: Path) -> None:
    """Before: the message quoted OpenCV's log as it is ('[ WARN:0@0.108] global
    grfmt_png.cpp:793 readFromStreamOrBuffer PNG input buffer ...')."""
    from rigkit.imagefile.decode import check_decoder_output

    printed = ("[ WARN:0@0.108] global grfmt_png.cpp:793 readFromStreamOrBuffer PNG "
               "input buffer is incomplete\n")
    with pytest.raises(InputError, match="decoder reports 'PNG input buffer is incomplete'"):
        check_decoder_output(tmp_path / "x.png", printed)


def test_grey_rows_at_the_bottom_are_a_cut_even_without_a_complaint() -> None:
    grey = texture((320, 240)) / 255
    grey[200:] = 0.5  # what a decoder fills in after the data ends
    assert "last 40 rows are one flat grey" in (picture_problem(grey) or "")


@pytest.mark.parametrize(
    "transform",
    [
        lambda g: 0.02 * g + 0.001 * np.random.default_rng(2).standard_normal(g.shape),  # dark
        lambda g: 0.6 + 0.01 * (g - g.mean()) / g.std(),  # haze: 1 % contrast
        lambda g: np.round((0.5 + 0.004 * (g - g.mean()) / g.std()) * 255) / 255,  # 8-bit, flat
        lambda g: np.clip(1.6 * g, 0, 1),  # bright: a third of it clipped
    ],
    ids=["dark-and-noisy", "hazy", "low-contrast-8-bit", "partly-clipped"],
)
def test_dark_hazy_and_low_contrast_frames_are_never_refused(transform) -> None:
    # The bundled example's left frame: a rendered field capture (sky, haze, shimmer).
    example = Path(__file__).resolve().parents[2] / "capture" / "example" / "raw" / "left.png"
    grey = load_linear_grey(example).astype(np.float64)
    assert picture_problem(np.clip(transform(grey), 0, 1).astype(np.float32)) is None


# --------------------------------------------------------------------------- one rule set


def test_the_same_file_at_every_position_is_refused_on_arrival(tmp_path: Path) -> None:
    frame = camera_dng(tmp_path / "a.dng")
    session = create_session(tmp_path / "s", rig_file(tmp_path, (320, 240)))
    session = add_frame(session, "left", frame)
    copy = tmp_path / "copy.dng"
    shutil.copy(frame, copy)
    for position in ("right", "back"):
        with pytest.raises(InputError, match=f"given for left and {position}"):
            add_frame(session, position, copy)
    assert raw_files(session.path) == ["a.dng"]


def test_raw_mixed_with_jpeg_is_refused_on_arrival(tmp_path: Path) -> None:
    session = create_session(tmp_path / "s", rig_file(tmp_path, (320, 240)))
    session = add_frame(session, "left", camera_dng(tmp_path / "a.dng"))
    jpeg = tmp_path / "b.jpg"
    cv2.imwrite(str(jpeg), texture((320, 240), seed=1).astype(np.uint8))
    with pytest.raises(InputError, match=r"RAW frames \(raw/a.dng\) mixed with ordinary images"):
        add_frame(session, "right", jpeg)
    assert raw_files(session.path) == ["a.dng"]


def test_session_show_flags_what_processing_would_refuse(tmp_path: Path, capsys) -> None:
    # A session edited by hand (or by an older rigkit) with the left file at two
    # positions: `session show` says so, as `rigkit process` would.
    import yaml

    session = create_session(tmp_path / "s", rig_file(tmp_path, (320, 240)))
    add_frame(session, "left", camera_dng(tmp_path / "a.dng"))
    data = yaml.safe_load((session.path / "session.yaml").read_text())
    data["frames"]["right"] = dict(data["frames"]["left"])
    (session.path / "session.yaml").write_text(yaml.safe_dump(data))
    assert main(["session", "show", str(session.path)]) == 0
    status = capsys.readouterr().out.splitlines()[-1]
    assert "raw/a.dng is the same file as raw/a.dng, given for left and right" in status
    assert "no back frame" in status


# --------------------------------------------------------------------------- messages


def test_a_jpeg_named_nef_is_named_a_jpeg(tmp_path: Path) -> None:
    path = tmp_path / "DSC_0001.NEF"
    cv2.imwrite(str(tmp_path / "x.jpg"), texture((64, 48)).astype(np.uint8))
    shutil.copy(tmp_path / "x.jpg", path)
    with pytest.raises(InputError, match=r"a JPEG image with a RAW file name \(.NEF\); rename"):
        load_linear_grey(path)


def test_a_gopro_gpr_says_it_is_unsupported(tmp_path: Path) -> None:
    path = tmp_path / "GOPR0001.GPR"
    path.write_bytes(camera_dng(tmp_path / "a.dng").read_bytes())
    with pytest.raises(InputError, match="GoPro GPR .* is not a RAW format LibRaw decodes"):
        load_linear_grey(path)


def test_a_frame_refused_for_its_size_never_enters_raw(tmp_path: Path) -> None:
    # Before: three refused frames left 5.9 MB of unrecorded files in raw/.
    session = create_session(tmp_path / "s", rig_file(tmp_path, (320, 240)))
    session = add_frame(session, "left", camera_dng(tmp_path / "a.dng"))
    for k, size in enumerate(((640, 480), (240, 320), (322, 240))):
        with pytest.raises(InputError, match=rf"{size[0]}x{size[1]} px, but the rig profile"):
            add_frame(session, "right", camera_dng(tmp_path / f"b{k}.dng", size, seed=k))
    assert raw_files(session.path) == ["a.dng"]
    assert not list((session.path / ".staging").iterdir())

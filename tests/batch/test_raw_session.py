"""A session of real RAW files end to end: DNG frames made from a rendered scene are
ingested, decoded linearly (cached by hash), checked by EXIF and turned into depth."""

from __future__ import annotations

import hashlib
from pathlib import Path

import cv2
import numpy as np
import pytest
import yaml

from rigkit.batch import process_session
from rigkit.capture import add_frame, add_target, create_session, load_session
from rigkit.capture.comparisons import LOG_NAME, read_rows
from rigkit.errors import InputError
from rigkit.synth import generate_scene
from rigkit.synth.session import rig_for_scene
from tests.conftest import SMALL
from tests.dngutil import write_dng

WHITE = 4095
EXIF = {
    "make": "NIKON",
    "model": "COOLPIX P1000",
    "focal_length_mm": 71.9,
    "exposure_time_s": 1 / 500,
    "f_number": 5.6,
    "iso": 200,
}
TIMES = {"left": "2026:11:22 10:00:00", "right": "2026:11:22 10:03:30",
         "back": "2026:11:22 10:07:10"}


def to_dng(png: Path, out: Path, exif: dict) -> Path:
    """A grey rendering as a Bayer mosaic of a neutral scene: every photosite gets the
    linear light of its pixel (the rendering's 8-bit values taken as sRGB-encoded)."""
    grey = cv2.imread(str(png), cv2.IMREAD_GRAYSCALE).astype(np.float64) / 255.0
    linear = np.where(grey <= 0.04045, grey / 12.92, ((grey + 0.055) / 1.055) ** 2.4)
    bayer = np.rint(0.6 * WHITE * linear).astype(np.uint16)  # exposed with headroom
    return write_dng(out, bayer, white_level=WHITE, exif=exif)


@pytest.fixture(scope="module")
def dng_frames(synth_session: Path, tmp_path_factory: pytest.TempPathFactory) -> dict:
    folder = tmp_path_factory.mktemp("card")
    return {
        view: to_dng(synth_session / "raw" / f"{view}.png", folder / f"DSCN{i:04d}.DNG",
                     {**EXIF, "datetime_original": TIMES[view]})
        for i, view in enumerate(("left", "right", "back"))
    }


def p1000_like_rig() -> dict:
    """The scene's rig, as a camera whose lens and sensor match the frames' EXIF."""
    rig = rig_for_scene(generate_scene(SMALL, seed=3))
    width_mm = EXIF["focal_length_mm"] * SMALL.width / SMALL.focal_px
    rig["camera"] = {
        "model": EXIF["model"],
        "sensor_mm": [width_mm, width_mm * SMALL.height / SMALL.width],
        "resolution": [SMALL.width, SMALL.height],
        "focal_length": {"mm": EXIF["focal_length_mm"], "tolerance_fraction": 0.005},
    }
    return rig


def raw_session(folder: Path, frames: dict, synth_session: Path) -> Path:
    rig = folder / "rig.yaml"
    rig.write_text(yaml.safe_dump(p1000_like_rig()))
    session = create_session(folder / "raw-session", rig)
    for view, path in frames.items():
        session = add_frame(session, view, path)
    for target in load_session(synth_session).targets:
        session = add_target(session, target.name, target.pixel, window_px=target.window_px,
                             readings=target.readings, note=target.note)
    return session.path


def test_raw_session_end_to_end(dng_frames: dict, synth_session: Path, tmp_path: Path) -> None:
    hashes = {v: hashlib.sha256(p.read_bytes()).hexdigest() for v, p in dng_frames.items()}
    path = raw_session(tmp_path, dng_frames, synth_session)
    session = load_session(path)
    assert session.frames["left"].file == "raw/DSCN0000.DNG"
    assert session.frames["back"].exif["model"] == "COOLPIX P1000"
    assert session.frames["left"].size_px == (960, 720)
    assert len(list((path / "derived").glob("*.linear.png"))) == 3  # decoded once, at ingest

    outcome = process_session(path, "20260101T000000Z-0007")
    rows = read_rows(path / LOG_NAME)
    assert len(rows) == 5 and all(r.status == "ok" for r in rows)
    for row in rows:
        true_range = float(session.target(row.target).note.split()[2])
        assert row.estimate_range_m == pytest.approx(true_range, rel=0.015)
    # No capture warning (same focal length and exposure, 7 minutes apart); at most the
    # note on the offset's share of depth error, which these small frames may get.
    assert [w for w in outcome.warnings if "disparity offset" not in w] == []
    for view, frame in load_session(path).frames.items():
        assert hashlib.sha256((path / frame.file).read_bytes()).hexdigest() == hashes[view]
        assert hashlib.sha256(dng_frames[view].read_bytes()).hexdigest() == hashes[view]


def test_focal_length_mismatch_stops_processing(
    dng_frames: dict, synth_session: Path, tmp_path: Path
) -> None:
    zoomed = to_dng(synth_session / "raw" / "back.png", tmp_path / "DSCN0009.DNG",
                    {**EXIF, "focal_length_mm": 53.9, "datetime_original": TIMES["back"]})
    path = raw_session(tmp_path, {**dng_frames, "back": zoomed}, synth_session)
    with pytest.raises(InputError, match=r"back frame \(DSCN0009.DNG\): FocalLength 53.9 mm "
                       r"differs from the left frame's 71.9 mm.*--force"):
        process_session(path, "20260101T000000Z-0008")
    assert not (path / "results").exists()


def test_exposure_mismatch_is_a_warning(
    dng_frames: dict, synth_session: Path, tmp_path: Path
) -> None:
    slower = to_dng(synth_session / "raw" / "right.png", tmp_path / "DSCN0010.DNG",
                    {**EXIF, "exposure_time_s": 1 / 250, "datetime_original": TIMES["right"]})
    path = raw_session(tmp_path, {**dng_frames, "right": slower}, synth_session)
    outcome = process_session(path, "20260101T000000Z-0009")
    assert outcome.ok
    assert any("ExposureTime 1/250 s differs" in w for w in outcome.warnings)

"""Georeferencing: the camera's orientation from the targets' pixels and laser
directions (Wahba/Kabsch), refusals, and points placed on the map in the tripod's UTM
zone where the laser says they are."""

from __future__ import annotations

import json
import math
from pathlib import Path

import laspy
import numpy as np
import pytest
import yaml

from rigkit.capture import load_session
from rigkit.capture.tripod import enu_direction
from rigkit.cli import main
from rigkit.errors import InputError
from rigkit.export import export_path
from rigkit.export.crs import utm_epsg
from rigkit.export.georef import wahba_rotation
from rigkit.geometry import rotvec_to_matrix
from tests.export.helpers import (
    TRIPOD,
    camera_orientation,
    depth_plane,
    georeferenced_session,
)

ROTATION = camera_orientation(azimuth=47.3, elevation=1.2, roll=0.4)
CORNERS = [(30, 280), (370, 20), (380, 270)]
"""Three targets near three corners of the 400 x 300 image."""


def test_wahba_rotation_recovers_a_rotation_from_two_directions() -> None:
    rng = np.random.default_rng(1)
    for _ in range(20):
        rotation = rotvec_to_matrix(rng.normal(size=3))
        camera = rng.normal(size=(2, 3))
        camera /= np.linalg.norm(camera, axis=1, keepdims=True)
        fitted = wahba_rotation(camera, camera @ rotation.T)
        assert np.allclose(fitted, rotation, atol=1e-9)
        assert np.linalg.det(fitted) == pytest.approx(1.0)


def test_enu_direction() -> None:
    assert np.allclose(enu_direction(0.0, 0.0), [0, 1, 0])
    assert np.allclose(enu_direction(90.0, 0.0), [1, 0, 0], atol=1e-12)
    assert np.allclose(enu_direction(180.0, 90.0), [0, 0, 1], atol=1e-12)


def test_utm_zones() -> None:
    assert utm_epsg(46.55, 7.98) == 32632
    assert utm_epsg(-33.86, 151.21) == 32756
    assert utm_epsg(0.0, 180.0) == 32660
    with pytest.raises(InputError, match="UTM covers"):
        utm_epsg(85.0, 10.0)


def _las_points(path: Path) -> np.ndarray:
    las = laspy.read(path)
    return np.column_stack([np.asarray(las.x), np.asarray(las.y), np.asarray(las.z)])


def test_a_georeferenced_las_puts_the_targets_where_the_laser_says(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """A camera of known orientation, three targets whose typed azimuths and
    inclinations are off by up to 0.1 deg: the LAS is in the tripod's UTM zone and each
    target's point lies within 2 m (here under 1 m) of the laser's."""
    session = georeferenced_session(tmp_path, ROTATION, CORNERS, [0.1, -0.1, 0.05])
    out = tmp_path / "out"
    assert main(["export", str(session), "--out", str(out), "--format", "las,ply",
                 "--quiet"]) == 0
    printed = capsys.readouterr().out
    assert "EPSG:32632 (WGS 84 / UTM zone 32N)" in printed and "residuals (deg)" in printed
    las = laspy.read(out / "geo.las")
    assert las.header.parse_crs().sub_crs_list[0].to_epsg() == 32632
    points = _las_points(out / "geo.las")
    index = np.cumsum(np.isfinite(depth_plane()).ravel()) - 1  # row-major, NaN skipped
    done = export_path(session, tmp_path / "again", ["ply"])
    assert done.georef is not None and done.georef.orientation.rms_residual_deg < 0.15
    for target, (u, v) in zip(load_session(session).targets, CORNERS, strict=True):
        reading = target.readings[0]
        laser = done.georef.enu_to_map(reading.slope_distance_m * enu_direction(
            reading.azimuth_deg, reading.inclination_deg)[None])
        assert np.linalg.norm(points[index[v * 400 + u]] - laser[0]) < 1.0
    # The tripod itself: its UTM coordinates, from an independent pyproj transform.
    import pyproj

    east, north = pyproj.Transformer.from_crs(4326, 32632, always_xy=True).transform(
        TRIPOD.lon_deg, TRIPOD.lat_deg)
    assert done.georef.origin == pytest.approx((east, north, TRIPOD.height_m), abs=1e-3)


def test_magnetic_azimuths_are_turned_by_the_declination(tmp_path: Path) -> None:
    session = georeferenced_session(tmp_path, ROTATION, CORNERS, [0.0, 0.0, 0.0])
    data = yaml.safe_load((session / "session.yaml").read_text())
    data["rig"]["values"]["rangefinder"] = {
        "protocol": "manual", "azimuth": "magnetic", "declination_deg": 3.2}
    for target in data["targets"]:
        for reading in target["readings"]:
            reading["azimuth_deg"] = (reading["azimuth_deg"] - 3.2) % 360
    (session / "session.yaml").write_text(yaml.safe_dump(data))
    done = export_path(session, tmp_path / "out", ["ply"])
    assert done.georef is not None
    assert np.allclose(done.georef.orientation.rotation, ROTATION, atol=1e-6)


def _error(args: list[str], capsys: pytest.CaptureFixture[str]) -> str:
    assert main(args) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1
    return err


@pytest.mark.parametrize(("pixels", "errors", "message"), [
    (CORNERS[:1], [0.0], "needs 2 or more targets with a laser azimuth and inclination, 1 "),
    ([(200, 150), (203, 151)], [0.0, 0.0],
     "the targets lie within 0.05 deg of each other in the image, under the 1.87 deg needed "
     "to fix the camera's roll; add a target near another corner"),
    (CORNERS, [0.0, 0.0, 3.0], "target T3's laser direction misses its pixel by"),
])
def test_georeferencing_refuses_with_one_line_and_auto_falls_back(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], pixels, errors, message: str
) -> None:
    """--frame map refuses with the cause; --frame auto (the default) exports in the
    camera frame and says the same cause in one line."""
    session = georeferenced_session(tmp_path, ROTATION, pixels, errors)
    out = tmp_path / "out"
    assert message in _error(["export", str(session), "--out", str(out), "--frame", "map"],
                             capsys)
    assert not out.exists() or not list(out.iterdir())
    assert main(["export", str(session), "--out", str(out), "--quiet"]) == 0
    printed = capsys.readouterr().out.splitlines()
    assert "  frame left camera: x right, y down, z forward, metres" in printed
    notes = [line for line in printed if line.startswith("  not on the map: ")]
    assert len(notes) == 1 and message in notes[0]
    assert load_session(session).tripod is not None  # the session had a position
    meta = json.loads((out / "geo.export.json").read_text())
    assert meta["place"]["frame"] == "camera" and message in meta["place"]["why_not_on_the_map"]


def test_without_a_tripod_position_auto_is_the_camera_frame(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    session = georeferenced_session(tmp_path, ROTATION, CORNERS, [0.0, 0.0, 0.0])
    data = yaml.safe_load((session / "session.yaml").read_text())
    del data["tripod"]
    (session / "session.yaml").write_text(yaml.safe_dump(data))
    done = export_path(session, tmp_path / "out", ["ply"])
    assert done.georef is None and done.frame.startswith("left camera")
    err = _error(["export", str(session), "--out", str(tmp_path / "o"), "--frame", "map"],
                 capsys)
    assert "no tripod position (rigkit session set-position)" in err
    assert math.isfinite(done.median_z_m)


def test_a_target_with_half_a_direction_is_named_when_left_out(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    session = georeferenced_session(tmp_path, ROTATION, CORNERS, [0.0, 0.0, 0.0])
    data = yaml.safe_load((session / "session.yaml").read_text())
    for reading in data["targets"][2]["readings"]:
        del reading["inclination_deg"]  # T3: an azimuth, no inclination
    (session / "session.yaml").write_text(yaml.safe_dump(data))
    assert main(["export", str(session), "--out", str(tmp_path / "out"), "--format", "ply",
                 "--quiet"]) == 0
    printed = capsys.readouterr().out
    assert "2 targets spanning" in printed
    assert "  left out: T3 has an azimuth but no inclination" in printed
    for reading in data["targets"][1]["readings"]:
        del reading["inclination_deg"]  # T2 too: one target left, and both named
    (session / "session.yaml").write_text(yaml.safe_dump(data))
    err = _error(["export", str(session), "--out", str(tmp_path / "out2"), "--frame", "map"],
                 capsys)
    assert "1 have them; T2 has an azimuth but no inclination; T3 has an azimuth" in err


def test_the_orientations_covariance_matches_the_scatter_of_fits() -> None:
    """Directions off by the instruments' sigma (azimuth 1 deg, inclination 0.25 deg):
    the fitted rotations scatter as orientation_covariance says (each axis's variance
    within 20 % over 400 fits), and more readings per target shrink it as 1/n."""
    from scipy.spatial.transform import Rotation

    from rigkit.capture.tripod import direction_angles
    from rigkit.export.georef import (
        AZIMUTH_SIGMA_DEG,
        INCLINATION_SIGMA_DEG,
        Sighting,
        orientation_covariance,
    )

    rng = np.random.default_rng(5)
    f = 4000.0
    pixels = [(-300, 200), (350, -250), (320, 260), (-10, -20)]
    rays = [np.array([u / f, v / f, 1.0]) / np.linalg.norm([u / f, v / f, 1.0])
            for u, v in pixels]
    true = [ROTATION @ ray for ray in rays]
    covariance = orientation_covariance([Sighting(f"T{i}", r, b) for i, (r, b) in
                                         enumerate(zip(rays, true, strict=True))])
    errors = []
    for _ in range(400):
        seen = []
        for b in true:
            azimuth, inclination = direction_angles(b)
            seen.append(enu_direction(azimuth + rng.normal(0, AZIMUTH_SIGMA_DEG),
                                      inclination + rng.normal(0, INCLINATION_SIGMA_DEG)))
        fitted = wahba_rotation(np.array(rays), np.array(seen))
        errors.append(Rotation.from_matrix(fitted @ ROTATION.T).as_rotvec())
    scatter = np.cov(np.array(errors).T)
    assert np.allclose(np.diag(scatter), np.diag(covariance), rtol=0.2)
    four = orientation_covariance([Sighting(f"T{i}", r, b, readings=4) for i, (r, b) in
                                   enumerate(zip(rays, true, strict=True))])
    assert np.allclose(four, covariance / 4)

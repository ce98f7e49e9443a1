"""A synthetic session placed on the map: the tripod recorded as a GPS would, and each
simulated reading's azimuth and inclination where the laser at the tripod sees its
target's ray-traced point."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from rigkit.capture import LaserReading, add_target, load_session
from rigkit.cli import main
from rigkit.errors import InputError
from rigkit.synth import load_scene
from rigkit.synth.placement import Placement, place_session
from tests.export.helpers import camera_orientation

SMALL = ["--seed", "2", "--width", "192", "--height", "144", "--quiet"]


def test_a_placed_session_has_the_lasers_directions(tmp_path: Path) -> None:
    out = tmp_path / "placed"
    assert main(["synth", str(out), *SMALL, "--session", "--targets", "3", "--position",
                 "46.55,7.98,1012,49.6", "--pointing", "47.3,-30,2"]) == 0
    session = load_session(out)
    tripod = session.tripod
    assert tripod is not None and (tripod.lat_deg, tripod.lon_deg, tripod.height_m) == (
        46.55, 7.98, 1012.0)
    assert tripod.height_datum == "gps" and tripod.geoid_separation_m == 49.6
    truth = load_scene(out)
    left = truth.cameras["left"]
    rotation = camera_orientation(47.3, -30.0, 2.0)  # the export tests' own construction
    assert len(session.targets) == 3
    for target in session.targets:
        u, v = target.pixel
        point = left.rays(np.array([u]), np.array([v]))[0] * truth.depth("left")[int(v), int(u)]
        east, north, up = rotation @ point
        (reading,) = target.readings
        assert reading.azimuth_deg == pytest.approx(math.degrees(math.atan2(east, north)) % 360,
                                                    abs=1e-6)
        assert reading.inclination_deg == pytest.approx(
            math.degrees(math.asin(up / np.linalg.norm(point))), abs=1e-6)
    assert "place" in (out / "history.log").read_text()


def test_only_simulated_readings_are_given_directions(tmp_path: Path) -> None:
    out = tmp_path / "mixed"
    assert main(["synth", str(out), *SMALL, "--session", "--targets", "1"]) == 0
    session = load_session(out)
    add_target(session, "typed", (60.0, 50.0), readings=[
        LaserReading(300.0, "2026-04-12T08:00:00Z", "manual")])
    before = (out / "session.yaml").read_bytes()
    with pytest.raises(InputError, match="target typed has readings that are not simulated"):
        place_session(out, Placement(46.55, 7.98, 1012.0))
    assert (out / "session.yaml").read_bytes() == before


@pytest.mark.parametrize(("args", "message"), [
    (["--position", "46.55,7.98,1012"], "--position places a --session on the map"),
    (["--session", "--position", "46.55,7.98"], "--position '46.55,7.98': expected 3 or 4"),
    (["--session", "--position", "95,7,0"], "latitude 95: expected -90 to 90"),
    (["--session", "--position", "46,7,0", "--pointing", "10,100"],
     "inclination 100: expected -90 to 90"),
])
def test_bad_placements_get_one_line(tmp_path: Path, capsys: pytest.CaptureFixture[str],
                                     args: list[str], message: str) -> None:
    assert main(["synth", str(tmp_path / "x"), *SMALL, *args]) == 2
    err = capsys.readouterr().err.strip()
    assert message in err and len(err.splitlines()) == 1

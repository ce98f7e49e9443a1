"""Georeferencing inputs in a session: the tripod's position (typed in or from a GPS),
the laser's azimuth and inclination per reading, and the rig profile's azimuth
reference (true or magnetic with a declination)."""

from __future__ import annotations

from pathlib import Path

import pytest
import yaml

from rigkit.capture import create_session, load_session
from rigkit.cli import main
from rigkit.errors import InputError
from rigkit.rig import load_rig, rig_to_dict
from rigkit.rig.profile import rig_from_data
from tests.conftest import rig_file

RIG = Path(__file__).resolve().parents[2] / "rigs" / "synthetic.yaml"


def session(folder: Path) -> Path:
    path = folder / "site"
    create_session(path, rig_file(folder, (64, 48)))
    return path


def test_a_typed_position_and_directions_round_trip(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    s = session(tmp_path)
    assert main(["session", "set-position", str(s), "--lat", "46.55123", "--lon", "7.98456",
                 "--height-m", "1012.5"]) == 0
    assert main(["session", "add-target", str(s), "--pixel", "30", "20", "--range-m", "300.5",
                 "--azimuth", "47.3", "--inclination", "1.2"]) == 0
    loaded = load_session(s)
    assert loaded.tripod is not None and loaded.tripod.source == "manual"
    assert (loaded.tripod.lat_deg, loaded.tripod.lon_deg, loaded.tripod.height_m) == (
        46.55123, 7.98456, 1012.5)
    reading = loaded.target("T1").readings[0]
    assert (reading.azimuth_deg, reading.inclination_deg) == (47.3, 1.2)
    assert "set-position lat 46.5512300" in (s / "history.log").read_text()
    assert main(["session", "show", str(s)]) == 0
    assert "tripod   46.5512300, 7.9845600, 1012.50 m (manual; height unknown)" in (
        capsys.readouterr().out)
    assert loaded.tripod.height_datum == "unknown" and loaded.tripod.ellipsoidal_height_m is None


def test_a_typed_height_says_what_it_is_measured_from(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    s = session(tmp_path)
    typed = ["session", "set-position", str(s), "--lat", "46.55", "--lon", "7.98",
             "--height-m", "1012.4"]
    assert main([*typed, "--height-datum", "epsg:5728"]) == 0
    tripod = load_session(s).tripod
    assert tripod is not None and tripod.height_datum == "EPSG:5728"
    assert main([*typed, "--height-datum", "Ellipsoidal"]) == 0
    tripod = load_session(s).tripod
    assert tripod is not None and tripod.ellipsoidal_height_m == 1012.4
    capsys.readouterr()
    for datum, message in (("EPSG:2056", "EPSG:2056 (CH1903+ / LV95): not a vertical CRS"),
                           ("EPSG:999999", "EPSG:999999: not a vertical CRS PROJ knows"),
                           ("msl", "height datum 'msl': expected ellipsoidal, gps, unknown")):
        assert main([*typed, "--height-datum", datum]) == 2
        err = capsys.readouterr().err.strip()
        assert message in err and len(err.splitlines()) == 1
    assert load_session(s).tripod == tripod  # refused: the recorded position stays


def test_a_session_from_before_heights_had_a_datum(tmp_path: Path) -> None:
    """A tripod written without height_datum: a GPS's is GGA's mean sea level, a typed
    one's is not known."""
    s = session(tmp_path)
    main(["session", "set-position", str(s), "--lat", "46", "--lon", "7", "--height-m", "5"])
    data = yaml.safe_load((s / "session.yaml").read_text())
    del data["tripod"]["height_datum"]
    (s / "session.yaml").write_text(yaml.safe_dump(data))
    assert load_session(s).tripod.height_datum == "unknown"
    data["tripod"]["source"] = "gps:/dev/ttyACM0"
    (s / "session.yaml").write_text(yaml.safe_dump(data))
    assert load_session(s).tripod.height_datum == "gps"


def test_a_position_from_a_simulated_gps(tmp_path: Path) -> None:
    s = session(tmp_path)
    url = "sim://gps?lat=-33.8568&lon=151.2153&height=58&interval=0.01&noise=2&seed=2"
    assert main(["session", "set-position", str(s), "--gps", url, "--fixes", "4"]) == 0
    tripod = load_session(s).tripod
    assert tripod is not None and tripod.fixes == 4 and tripod.source == f"gps:{url}"
    assert tripod.lat_deg == pytest.approx(-33.8568, abs=3 / 111_000)
    assert tripod.raw is not None and tripod.raw.startswith("$GPGGA")
    # GGA's geoid separation is kept: the ellipsoidal height is the altitude plus it.
    assert tripod.height_datum == "gps" and tripod.geoid_separation_m == pytest.approx(47.3)
    assert tripod.ellipsoidal_height_m == pytest.approx(58 + 47.3)
    assert load_session(s).tripod == tripod  # through session.yaml and back


@pytest.mark.parametrize(("args", "message"), [
    (["--lat", "95", "--lon", "7", "--height-m", "0"], "latitude 95: expected -90 to 90"),
    (["--lat", "46", "--lon", "7"], "give all of --lat, --lon and --height-m, or --gps URL"),
    (["--lat", "46", "--gps", "sim://gps"], "not both"),
    (["--height-datum", "ellipsoidal", "--gps", "sim://gps"], "not both"),
    (["--gps", "sim://gps?silent=1", "--timeout", "0.2"], "no GPS fix from sim://gps"),
])
def test_bad_positions_get_one_line(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], args: list[str], message: str
) -> None:
    s = session(tmp_path)
    before = (s / "session.yaml").read_text()
    assert main(["session", "set-position", str(s), *args]) == 2
    err = capsys.readouterr().err.strip()
    assert message in err and len(err.splitlines()) == 1
    assert (s / "session.yaml").read_text() == before


@pytest.mark.parametrize(("args", "message"), [
    (["--azimuth", "360"], "azimuth 360: expected 0 to 360 degrees"),
    (["--inclination", "-91"], "inclination -91: expected -90 to 90 degrees"),
])
def test_bad_directions_get_one_line(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], args: list[str], message: str
) -> None:
    s = session(tmp_path)
    assert main(["session", "add-target", str(s), "--pixel", "3", "2", "--range-m", "300",
                 *args]) == 2
    assert message in capsys.readouterr().err


def test_a_device_reading_keeps_its_azimuth(tmp_path: Path) -> None:
    s = session(tmp_path)
    url = "sim://trupulse?distance=300&azimuth=212.4&inclination=-1.5&interval=0.01"
    assert main(["session", "add-target", str(s), "--pixel", "3", "2", "--device", url,
                 "--timeout", "5"]) == 0
    reading = load_session(s).target("T1").readings[0]
    assert (reading.azimuth_deg, reading.inclination_deg) == (212.4, -1.5)


def test_the_field_tui_keeps_the_azimuth_and_360_is_north() -> None:
    from rigkit.capture.readings import reading_from_device
    from rigkit.rangefinder import encode_trupulse_hv, parse_trupulse

    frame = encode_trupulse_hv(300.0, inclination_deg=0.5, azimuth_deg=360.0).strip()
    reading = reading_from_device(parse_trupulse(frame, 0.0), "trupulse:sim://")
    assert (reading.azimuth_deg, reading.inclination_deg) == (0.0, 0.5)


@pytest.mark.parametrize(("edit", "key"), [
    (lambda d: d["tripod"].update(lat_deg=91.0), "tripod: latitude 91"),
    (lambda d: d["tripod"].update(height_m="1012 m"), "tripod.height_m: must be a number"),
    (lambda d: d["tripod"].update(datum="WGS84"), "tripod.datum: unknown key"),
    (lambda d: d["tripod"].update(height_datum="NN"), "tripod.height_datum: height datum 'NN'"),
    (lambda d: d["tripod"].update(geoid_separation_m=470), "tripod.geoid_separation_m: must "
     "be within -150 to 150 m"),
    (lambda d: d["targets"][0]["readings"][0].update(azimuth_deg=400),
     r"targets\[0\].readings\[0\].azimuth_deg: must be at least 0 and under 360"),
])
def test_bad_values_in_session_yaml_name_the_key(tmp_path: Path, edit, key: str) -> None:
    s = session(tmp_path)
    main(["session", "set-position", str(s), "--lat", "46", "--lon", "7", "--height-m", "5"])
    main(["session", "add-target", str(s), "--pixel", "3", "2", "--range-m", "300",
          "--azimuth", "10", "--inclination", "0"])
    data = yaml.safe_load((s / "session.yaml").read_text())
    edit(data)
    (s / "session.yaml").write_text(yaml.safe_dump(data))
    with pytest.raises(InputError, match=key):
        load_session(s)


def _rangefinder(values: dict) -> object:
    data = rig_to_dict(load_rig(RIG))
    data["rangefinder"] = {"protocol": "trupulse", **values}
    return rig_from_data(data, Path("rig.yaml")).rangefinder


def test_the_rig_profile_says_whether_azimuths_are_magnetic() -> None:
    spec = _rangefinder({"azimuth": "magnetic", "declination_deg": -3.5})
    assert spec.true_azimuth_deg(2.0) == pytest.approx(358.5)
    data = rig_to_dict(load_rig(RIG))
    data["rangefinder"] = {"protocol": "trupulse", "azimuth": "magnetic",
                           "declination_deg": -3.5}
    again = rig_to_dict(rig_from_data(data, Path("rig.yaml")))
    assert again["rangefinder"] == data["rangefinder"]
    assert _rangefinder({}).true_azimuth_deg(2.0) == 2.0


@pytest.mark.parametrize(("values", "message"), [
    ({"azimuth": "grid"}, "rangefinder.azimuth: must be 'true' or 'magnetic'"),
    ({"azimuth": "magnetic"}, "rangefinder.declination_deg: missing"),
    ({"declination_deg": 3.0}, "applies to 'azimuth: magnetic' only"),
    ({"azimuth": "magnetic", "declination_deg": 200}, "between -180 and 180"),
])
def test_bad_azimuth_references_are_refused(values: dict, message: str) -> None:
    with pytest.raises(InputError, match=message):
        _rangefinder(values)


def test_a_position_utm_cannot_hold_is_recorded_with_a_warning(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    s = session(tmp_path)
    assert main(["session", "set-position", str(s), "--lat", "86.1", "--lon", "12.0",
                 "--height-m", "40"]) == 0
    err = capsys.readouterr().err
    assert "warning: latitude 86.1: UTM covers 80 S to 84 N only" in err
    assert "--frame camera" in err
    assert load_session(s).tripod is not None
    assert main(["session", "set-position", str(s), "--lat", "46.5", "--lon", "7.9",
                 "--height-m", "1000"]) == 0
    assert capsys.readouterr().err == ""

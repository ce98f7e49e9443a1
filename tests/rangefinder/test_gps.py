"""The GPS receiver: GGA parsing on published and scripted sentences, the reader over
a scripted port, and the sim://gps simulator."""

from __future__ import annotations

import pytest
import serial

from rigkit.rangefinder import ChecksumError, FrameError, Notice, PortError, ReadTimeout
from rigkit.rangefinder.gps import (
    GpsFix,
    GpsReceiver,
    encode_gga,
    mean_position,
    open_gps,
    parse_nmea,
    split_nmea,
)
from rigkit.rangefinder.trupulse import trupulse_sentence
from tests.rangefinder.test_driver import ScriptedPort

# The GGA example of the NMEA 0183 references (e.g. gpsd's "NMEA Revealed").
SPEC = b"$GPGGA,123519,4807.038,N,01131.000,E,1,08,0.9,545.4,M,46.9,M,,*47"


def test_the_published_example() -> None:
    fix = parse_nmea(SPEC)
    assert isinstance(fix, GpsFix)
    assert fix.lat_deg == pytest.approx(48 + 7.038 / 60)
    assert fix.lon_deg == pytest.approx(11 + 31.0 / 60)
    assert (fix.height_m, fix.quality, fix.satellites, fix.hdop) == (545.4, 1, 8, 0.9)
    assert fix.geoid_separation_m == 46.9


@pytest.mark.parametrize(("lat", "lon"), [(-33.8568, 151.2153), (64.1466, -21.9426),
                                          (-0.5, -179.99)])
def test_encode_and_parse_round_trip_in_every_hemisphere(lat: float, lon: float) -> None:
    sentence = encode_gga(lat, lon, 58.25, utc_s=45296.5)
    assert sentence.startswith(b"$GPGGA,123456.50,") and sentence.endswith(b"\r\n")
    fix = parse_nmea(sentence.strip())
    assert isinstance(fix, GpsFix)
    assert (fix.lat_deg, fix.lon_deg) == pytest.approx((lat, lon), abs=1e-7)
    assert fix.height_m == 58.25 and fix.geoid_separation_m == 47.3


def test_the_geoid_separation_is_kept_and_its_absence_said() -> None:
    """GGA's g.g: the geoid's height above the ellipsoid, kept with the fix (negative
    where the geoid lies below it); a receiver that leaves it empty gives None, and an
    average over fixes has one only when every fix sent it."""
    low = parse_nmea(encode_gga(-8.0, 77.0, 12.0, geoid_separation_m=-102.5).strip())
    none = parse_nmea(encode_gga(46.5, 7.5, 500.0, geoid_separation_m=None).strip())
    assert isinstance(low, GpsFix) and low.geoid_separation_m == -102.5
    assert isinstance(none, GpsFix) and none.geoid_separation_m is None
    assert mean_position([low, low]).geoid_separation_m == -102.5
    assert mean_position([low, none]).geoid_separation_m is None
    with pytest.raises(FrameError, match="geoid separation unit 'F'"):
        parse_nmea(sentence("GPGGA,1,4807.038,N,01131.000,E,1,08,0.9,545.4,M,47.0,F,,"))


def sentence(body: str) -> bytes:
    """``$body*CS`` with its checksum."""
    return trupulse_sentence(body.split(",")).strip()


def test_other_talkers_sentences_and_no_fix() -> None:
    gn = parse_nmea(sentence("GNGGA,1,4807.038,S,01131.000,W,2,12,0.6,5.0,M,,M,,"))
    assert isinstance(gn, GpsFix) and gn.lat_deg < 0 and gn.lon_deg < 0 and gn.quality == 2
    no_fix = parse_nmea(encode_gga(0, 0, 0, quality=0, satellites=3))
    assert isinstance(no_fix, Notice) and no_fix.error == "no fix yet (3 satellites)"
    rmc = parse_nmea(b"$GPRMC,,V,,,,,,,,,*31")
    assert isinstance(rmc, Notice) and rmc.kind == "GPRMC" and rmc.error is None


@pytest.mark.parametrize(("frame", "error", "message"), [
    (SPEC.replace(b"*47", b"*48"), ChecksumError, "bad checksum"),
    (sentence("GPGGA,123519,4807.038,N"), FrameError, "3 fields"),
    (sentence("GPGGA,1,4867.0,N,01131.0,E,1,08,0.9,545.4,M,,M,,"), FrameError, "out of range"),
    (sentence("GPGGA,1,4807.0,X,01131.0,E,1,08,0.9,545.4,M,,M,,"), FrameError, "hemisphere"),
    (sentence("GPGGA,1,4807.0,N,01131.0,E,1,08,0.9,545.4,F,,M,,"), FrameError, "unit 'F'"),
    (b"GPGGA without a dollar", FrameError, "no leading"),
])
def test_malformed_sentences_are_refused(frame: bytes, error: type, message: str) -> None:
    with pytest.raises(error, match=message):
        parse_nmea(frame)


def test_the_reader_skips_noise_and_waits_for_a_fix() -> None:
    script = [b"\x00\x17junk$GPGG", b"A,cut\r\n", encode_gga(0, 0, 0, quality=0),
              SPEC.replace(b"*47", b"*00") + b"\r\n", SPEC[:30], SPEC[30:] + b"\r\n"]
    with GpsReceiver(ScriptedPort(script), name="scripted", timeout=2.0) as gps:
        fix = gps.read()
    assert fix.raw == SPEC
    frames, rest = split_nmea(b"$A*00\r\n$B")
    assert frames == [b"$A*00"] and rest == b"$B"


@pytest.mark.parametrize(("script", "message"), [
    ([], "nothing received"),
    ([encode_gga(0, 0, 0, quality=0)] * 3, r"3 GGA sentences, no fix yet \(9 satellites\)"),
    ([b"$GPRMC,,V,,,,,,,,,*31\r\n"], "none a GGA"),
])
def test_timeouts_say_what_arrived(script: list[bytes], message: str) -> None:
    with GpsReceiver(ScriptedPort(script), name="scripted", timeout=0.2) as gps, \
            pytest.raises(ReadTimeout, match=message):
        gps.read()


def test_a_pulled_cable_is_a_port_error() -> None:
    port = ScriptedPort([serial.SerialException("device reports readiness but no data")])
    with GpsReceiver(port, name="usb", timeout=1.0) as gps, \
            pytest.raises(PortError, match="lost connection to usb"):
        gps.read()


def test_the_simulator_through_a_url() -> None:
    url = ("sim://gps?lat=-33.8568&lon=151.2153&height=58&interval=0.02&noise=2&nofix=2"
           "&other=0.5&garbage=0.3&bad_checksum=0.2&seed=4")
    with open_gps(url, timeout=2.0) as gps:
        fixes = [gps.read() for _ in range(8)]
    mean = mean_position(fixes)
    assert mean.lat_deg == pytest.approx(-33.8568, abs=3 / 111_000)  # within 3 m
    assert mean.lon_deg == pytest.approx(151.2153, abs=3 / 92_000) and mean.height_m == 58.0
    assert mean.geoid_separation_m == pytest.approx(47.3) and mean.count == 8


def test_simulator_options_are_checked() -> None:
    with pytest.raises(PortError, match="option distance does not apply to gps"):
        open_gps("sim://gps?distance=300")
    with pytest.raises(PortError, match="lat 95.0"):
        open_gps("sim://gps?lat=95")

"""Pure parsing/encoding of the TruPulse and Vectronix rangefinder protocols.

Published example frames come from the vendors' manuals (LTI TruPulse 200
User's Manual, Serial Data Interface; Safran Vectronix LRF 6019/6042/7047
integrator manuals). Their checksums were recomputed here; the few published
examples whose checksum does not match their text are kept as negative cases.
"""

from __future__ import annotations

import dataclasses
import math

import pytest

from rigkit.errors import InputError, RigkitError
from rigkit.rangefinder import (
    PROTOCOLS,
    ChecksumError,
    FrameError,
    Notice,
    Reading,
    additive_checksum,
    depth_from_range,
    encode_trupulse_hv,
    get_protocol,
    nmea_checksum,
    parse_trupulse,
    parse_vectronix,
    split_trupulse,
    split_vectronix,
    trupulse_sentence,
    vectronix_frame,
)
from rigkit.rangefinder.trupulse import FOOT_M, YARD_M
from rigkit.rangefinder.vectronix import vectronix_range_field

T0 = 1_700_000_000.0

# TruPulse 200 User's Manual (6th ed.), Section 8 "Serial Data Interface".
TRUPULSE_PUBLISHED_OK = [
    b"$PLTIT,HV,11.80,M,0.00,D,3.70,D,11.80,M*63",  # high-quality target
    b"$PLTIT,HV,7.01,M,0.00,D,3.00,D,7.01,M*64",  # low-quality target
    b"$PLTIT,HV,,,0.00,D,29.10,D,,*5D",  # inclination only
    b"$PLTIT,HV,16.00,F,0.00,D,-1.20,D,16.00,F*49",  # height routine, HD shot
    b"$PLTIT,HV,,,0.00,D,-19.10,D,,*73",
    b"$PLTIT,HV,,,0.00,D,32.40,D,,*52",
    b"$PLTIT,HT,15.70,F*0E",
    b"$PLTIT,HT,5.50,M*36",
    b"$PLTIT,HT,2.01,M*35",
    b"$PLTIT,ID,TP200,1.02,*73",
]
# Missing-line example in the same manual: these checksums do not match the text
# (recomputed 63, 5B and 79), so a careful parser must reject them.
TRUPULSE_PUBLISHED_BAD = [
    b"$PLTIT,HV,6.00,Y,0.00,D,7.20,D,6.10,Y*68",
    b"$PLTIT,HV,5.90,Y,0.00,D,11.60,D,6.00,Y*5D",
    b"$PLTIT,ML,8.10,Y,0.00,D,3.20,D,8.10,Y*74",
]
# Vectronix LRF integrator manuals (6019, 6042, 6742, 7047).
VECTRONIX_PUBLISHED_OK = [
    b">LM,Md,3*D5",  # range request, 3 targets
    b">AC*84",  # acknowledge
    b">LM,Md,v0006091,R000E301,R000E301*46",  # range response
    b">LM,Mf,v0123400,v0432100,R000E301*57",  # fake-range self test
    b">NA,2*ED",  # not acknowledged: invalid parameter
    b">NA,0*EB",  # not acknowledged: checksum error
    b">LM,Md,3,0*31",
    b">LM,Mf,3*D7",
    b">LM,Br,4*D9",
]
# The manuals' range table shows this frame with the checksum of the frame above (46);
# its own checksum is 66.
VECTRONIX_PUBLISHED_BAD = b">LM,Md,v0006091,v0108750,R000E301*46"


@pytest.mark.parametrize("frame", TRUPULSE_PUBLISHED_OK)
def test_nmea_checksum_matches_published_trupulse_examples(frame: bytes) -> None:
    body, _, given = frame[1:].rpartition(b"*")
    assert nmea_checksum(body) == int(given, 16)


@pytest.mark.parametrize("frame", VECTRONIX_PUBLISHED_OK)
def test_additive_checksum_matches_published_vectronix_examples(frame: bytes) -> None:
    body, _, given = frame[1:].rpartition(b"*")
    assert additive_checksum(body) == int(given, 16)


def test_published_high_quality_hv_sentence() -> None:
    reading = parse_trupulse(TRUPULSE_PUBLISHED_OK[0], T0)
    assert isinstance(reading, Reading)
    assert reading.slope_distance_m == pytest.approx(11.8)
    assert reading.horizontal_distance_m == pytest.approx(11.8)
    assert reading.inclination_deg == pytest.approx(3.7)
    assert reading.azimuth_deg == 0.0
    assert reading.unit == "m"
    assert reading.low_quality is False
    assert reading.timestamp == T0
    assert reading.raw == TRUPULSE_PUBLISHED_OK[0]
    assert reading.protocol == "trupulse"
    assert reading.targets_m == (reading.slope_distance_m,)


def test_last_digit_is_the_target_quality_flag_not_a_distance_digit() -> None:
    reading = parse_trupulse(TRUPULSE_PUBLISHED_OK[1], T0)
    assert isinstance(reading, Reading)
    assert reading.low_quality is True
    assert reading.slope_distance_m == pytest.approx(7.0)
    assert reading.horizontal_distance_m == pytest.approx(7.0)


def test_feet_are_converted_and_negative_inclination_is_below_horizontal() -> None:
    reading = parse_trupulse(TRUPULSE_PUBLISHED_OK[3], T0)
    assert isinstance(reading, Reading)
    assert reading.unit == "ft"
    assert reading.slope_distance_m == pytest.approx(16.0 * FOOT_M)
    assert reading.inclination_deg == pytest.approx(-1.2)


def test_yards_are_converted() -> None:
    frame = trupulse_sentence(
        ["PLTIT", "HV", "327.80", "Y", "12.50", "D", "2.10", "D", "328.00", "Y"]
    )
    reading = parse_trupulse(frame.rstrip(), T0)
    assert isinstance(reading, Reading)
    assert reading.unit == "yd"
    assert reading.slope_distance_m == pytest.approx(328.0 * YARD_M)
    assert reading.horizontal_distance_m == pytest.approx(327.8 * YARD_M)
    assert reading.azimuth_deg == pytest.approx(12.5)


@pytest.mark.parametrize("frame", TRUPULSE_PUBLISHED_OK[2:3] + TRUPULSE_PUBLISHED_OK[4:6])
def test_inclination_only_shot_is_not_a_reading(frame: bytes) -> None:
    notice = parse_trupulse(frame, T0)
    assert isinstance(notice, Notice)
    assert notice.kind == "HV"
    assert notice.known and notice.error is None


def test_height_and_id_sentences_are_notices() -> None:
    height = parse_trupulse(TRUPULSE_PUBLISHED_OK[6], T0)
    assert isinstance(height, Notice)
    assert (height.kind, height.fields) == ("HT", ("15.70", "F"))
    ident = parse_trupulse(TRUPULSE_PUBLISHED_OK[9], T0)
    assert isinstance(ident, Notice)
    assert (ident.kind, ident.fields, ident.known) == ("ID", ("TP200", "1.02"), True)


def test_missing_line_sentence_is_a_notice() -> None:
    frame = trupulse_sentence(["PLTIT", "ML", "8.10", "Y", "0.00", "D", "3.20", "D", "8.10", "Y"])
    notice = parse_trupulse(frame, T0)
    assert isinstance(notice, Notice)
    assert notice.kind == "ML"


@pytest.mark.parametrize("frame", TRUPULSE_PUBLISHED_BAD)
def test_published_examples_with_wrong_checksums_are_rejected(frame: bytes) -> None:
    with pytest.raises(ChecksumError, match="bad checksum"):
        parse_trupulse(frame, T0)


def test_trailing_comma_before_checksum_and_lower_case_hex_are_accepted() -> None:
    body = b"PLTIT,HV,301.90,M,47.30,D,1.20,D,302.00,M,"
    frame = b"$" + body + b"*" + f"{nmea_checksum(body):02x}".encode() + b"\r\n"
    reading = parse_trupulse(frame, T0)
    assert isinstance(reading, Reading)
    assert reading.slope_distance_m == pytest.approx(302.0)


def test_unknown_types_and_talkers_are_unknown_notices() -> None:
    unknown_type = parse_trupulse(trupulse_sentence(["PLTIT", "ZZ", "1"]), T0)
    other_talker = parse_trupulse(trupulse_sentence(["GPGGA", "123519", "4807.038", "N"]), T0)
    assert isinstance(unknown_type, Notice) and not unknown_type.known
    assert isinstance(other_talker, Notice) and other_talker.kind == "GPGGA"
    assert not other_talker.known


@pytest.mark.parametrize(
    ("frame", "message"),
    [
        (b"PLTIT,HV,1.00,M*00", "no leading"),
        (b"$PLTIT,HV,11.80,M,0.00,D,3.70,D,11.80,M", "without checksum"),
        (b"$PLTIT,HV,11.80,M,0.00,D,3.70,D,11.80,M*6", "malformed checksum"),
        (b"$PLTIT,HV,11.80,M,0.00,D,3.70,D,11.80,M*XY", "malformed checksum"),
        (b"$PLTIT,HV,11.80,M\xff*00", "non-ASCII"),
        (trupulse_sentence(["PLTIT", "HV", "1.00", "M"]), "2 fields, expected 8"),
        (
            trupulse_sentence(["PLTIT", "HV", "", "", "0", "D", "1", "D", "abc", "M"]),
            "not a number",
        ),
        (trupulse_sentence(["PLTIT", "HV", "", "", "0", "D", "1", "D", "-5.00", "M"]), "distance"),
        (trupulse_sentence(["PLTIT", "HV", "", "", "0", "D", "1", "D", "5.00", "K"]), "unit 'K'"),
        (trupulse_sentence(["PLTIT", "HV", "", "", "0", "R", "1", "D", "5.00", "M"]), "unit 'R'"),
        (trupulse_sentence(["PLTIT", "HV", "", "", "0", "D", "up", "D", "5.00", "M"]), "inclin"),
        (trupulse_sentence(["PLTIT", ""]), "without a message type"),
    ],
)
def test_malformed_trupulse_frames_raise_frame_error(frame: bytes, message: str) -> None:
    with pytest.raises(FrameError, match=message) as caught:
        parse_trupulse(frame, T0)
    assert "\n" not in str(caught.value)
    assert not isinstance(caught.value, ChecksumError)


def test_distance_without_quality_digit_is_taken_at_face_value() -> None:
    frame = trupulse_sentence(["PLTIT", "HV", "", "", "", "", "0.00", "D", "302.5", "M"])
    reading = parse_trupulse(frame, T0)
    assert isinstance(reading, Reading)
    assert reading.slope_distance_m == pytest.approx(302.5)
    assert reading.low_quality is None
    assert reading.azimuth_deg is None and reading.horizontal_distance_m is None


@pytest.mark.parametrize("unit", ["M", "F", "Y"])
@pytest.mark.parametrize("low_quality", [False, True])
def test_encode_then_parse_round_trips_within_resolution(unit: str, low_quality: bool) -> None:
    frame = encode_trupulse_hv(
        292.0, inclination_deg=-4.25, azimuth_deg=181.5, unit=unit, low_quality=low_quality
    )
    assert frame.endswith(b"\r\n")
    reading = parse_trupulse(frame, T0)
    assert isinstance(reading, Reading)
    resolution = {"M": 0.1, "F": 0.1 * FOOT_M, "Y": 0.1 * YARD_M}[unit]
    assert reading.slope_distance_m == pytest.approx(292.0, abs=resolution / 2 + 1e-9)
    expected_hd = 292.0 * math.cos(math.radians(4.25))
    assert reading.horizontal_distance_m == pytest.approx(expected_hd, abs=resolution / 2 + 1e-9)
    assert reading.inclination_deg == pytest.approx(-4.25)
    assert reading.azimuth_deg == pytest.approx(181.5)
    assert reading.low_quality is low_quality


def test_encode_rejects_unknown_unit() -> None:
    with pytest.raises(InputError, match="unknown TruPulse unit"):
        encode_trupulse_hv(1.0, inclination_deg=0.0, azimuth_deg=None, unit="K")


def test_reading_is_frozen_and_json_friendly() -> None:
    reading = parse_trupulse(TRUPULSE_PUBLISHED_OK[0], T0)
    assert isinstance(reading, Reading)
    with pytest.raises(dataclasses.FrozenInstanceError):
        reading.slope_distance_m = 1.0  # type: ignore[misc]
    data = reading.to_json_dict()
    assert data["slope_distance_m"] == pytest.approx(11.8)
    assert data["raw"] == TRUPULSE_PUBLISHED_OK[0].decode()
    assert str(data["time_utc"]).startswith("2023-11-14T22:13:20")


# -- framing -------------------------------------------------------------------


def test_split_separates_noise_partial_lines_and_keeps_the_unfinished_rest() -> None:
    good = b"$PLTIT,HT,5.50,M*36"
    stream = b"\x00\x17noise\r\n" + b"$PLTIT,HV,30" + good + b"\r\n" + good + b"\n\r" + b"$PLT"
    chunks, rest = split_trupulse(stream)
    assert chunks == [b"\x00\x17noise\r\n", b"$PLTIT,HV,30", good, good]
    assert rest == b"$PLT"
    chunks, rest = split_trupulse(rest + b"IT,HT,2.01,M*35\r")
    assert chunks == [b"$PLTIT,HT,2.01,M*35"] and rest == b""


def test_split_flushes_an_endless_unterminated_frame() -> None:
    chunks, rest = split_trupulse(b"$" + b"A" * 200)
    assert chunks == [b"$" + b"A" * 200] and rest == b""


def test_split_vectronix_cuts_prompts_and_frames() -> None:
    stream = b"<>AC*84\r>LM,Md,v0006091,R000E301,R000E301*46\r<>NA,0*EB\r!>LM"
    chunks, rest = split_vectronix(stream)
    assert chunks == [
        b"<",
        b">AC*84",
        b">LM,Md,v0006091,R000E301,R000E301*46",
        b"<",
        b">NA,0*EB",
        b"!",
    ]
    assert rest == b">LM"


def test_split_vectronix_treats_a_frame_cut_by_a_prompt_as_noise() -> None:
    chunks, rest = split_vectronix(b">LM,Md,v00!")
    assert chunks == [b">LM,Md,v00", b"!"] and rest == b""
    with pytest.raises(FrameError):
        parse_vectronix(chunks[0], T0)


# -- Vectronix -----------------------------------------------------------------


def test_published_vectronix_range_response() -> None:
    reading = parse_vectronix(VECTRONIX_PUBLISHED_OK[2], T0)
    assert isinstance(reading, Reading)
    assert reading.slope_distance_m == pytest.approx(60.91)
    assert reading.targets_m == (pytest.approx(60.91),)
    assert reading.unit == "cm"
    assert reading.inclination_deg is None and reading.horizontal_distance_m is None
    assert reading.protocol == "vectronix"


def test_published_fake_range_lists_all_valid_targets_best_first() -> None:
    reading = parse_vectronix(VECTRONIX_PUBLISHED_OK[3], T0)
    assert isinstance(reading, Reading)
    assert reading.targets_m == (pytest.approx(1234.0), pytest.approx(4321.0))
    assert reading.slope_distance_m == pytest.approx(1234.0)


def test_published_vectronix_frame_with_the_neighbours_checksum_is_rejected() -> None:
    with pytest.raises(ChecksumError, match="computed 66"):
        parse_vectronix(VECTRONIX_PUBLISHED_BAD, T0)


def test_acknowledge_prompts_and_nacks() -> None:
    ack = parse_vectronix(b">AC*84\r", T0)
    assert isinstance(ack, Notice) and ack.kind == "AC" and ack.error is None
    nack = parse_vectronix(VECTRONIX_PUBLISHED_OK[4], T0)
    assert isinstance(nack, Notice) and nack.kind == "NA"
    assert nack.error is not None and "invalid parameter" in nack.error
    ok, failed = parse_vectronix(b"<", T0), parse_vectronix(b"!", T0)
    assert isinstance(ok, Notice) and ok.error is None
    assert isinstance(failed, Notice) and failed.error is not None


def test_response_without_a_valid_target_is_an_error_notice() -> None:
    frame = vectronix_frame("LM,Md,R000E301,T0000001,R000E301")
    notice = parse_vectronix(frame, T0)
    assert isinstance(notice, Notice)
    assert notice.error is not None and "R000E301" in notice.error and "T0000001" in notice.error


def test_other_vectronix_messages() -> None:
    baud = parse_vectronix(vectronix_frame("LM,Br,4"), T0)
    assert isinstance(baud, Notice) and baud.known and baud.kind == "Br"
    foreign = parse_vectronix(vectronix_frame("XX,Md,1"), T0)
    assert isinstance(foreign, Notice) and not foreign.known


@pytest.mark.parametrize(
    ("frame", "message"),
    [
        (b"LM,Md,3*D5", "no leading"),
        (vectronix_frame("LM,Md"), "without ranges"),
        (vectronix_frame("LM,Md,v123"), "malformed range field"),
        (vectronix_frame("LM,Md,x0001000"), "malformed range field"),
        (vectronix_frame("LM,Md,v00010A0"), "not a number of centimetres"),
    ],
)
def test_malformed_vectronix_frames_raise_frame_error(frame: bytes, message: str) -> None:
    with pytest.raises(FrameError, match=message):
        parse_vectronix(frame, T0)


def test_vectronix_encoding_helpers() -> None:
    assert vectronix_frame("LM,Md,3") == b">LM,Md,3*D5\r"
    assert vectronix_range_field(302.004) == "v0030200"
    assert vectronix_range_field(None) == "R000E301"


# -- registry and geometry ------------------------------------------------------


def test_protocol_registry() -> None:
    assert set(PROTOCOLS) == {"trupulse", "vectronix"}
    assert get_protocol("vectronix").request == b">LM,Md,3*D5\r"
    assert get_protocol("trupulse").request_by_default is False
    with pytest.raises(InputError, match="unknown rangefinder protocol 'leica'"):
        get_protocol("leica")


def test_frame_errors_are_rigkit_errors() -> None:
    assert issubclass(ChecksumError, FrameError)
    assert issubclass(FrameError, RigkitError)


FX = FY = 53_251.0  # the P1000 at 400 mm equivalent
CX, CY = 2304.0, 1728.0


def test_depth_on_axis_equals_range() -> None:
    assert depth_from_range(302.0, (CX, CY), fx=FX, fy=FY, cx=CX, cy=CY) == pytest.approx(302.0)


def test_depth_three_degrees_off_axis_is_0_14_percent_short() -> None:
    u = CX + FX * math.tan(math.radians(3.0))
    depth = depth_from_range(300.0, (u, CY), fx=FX, fy=FY, cx=CX, cy=CY)
    assert 1 - depth / 300.0 == pytest.approx(0.00137, abs=1e-5)


def test_depth_with_aperture_offset_puts_the_spot_at_the_measured_range() -> None:
    offset = (0.10, 0.08, 0.25)
    pixel = (CX + 800.0, CY - 500.0)
    depth = depth_from_range(234.0, pixel, fx=FX, fy=FY, cx=CX, cy=CY, offset_m=offset)
    x, y = (pixel[0] - CX) / FX, -(pixel[1] - CY) / FY
    point = (x * depth, y * depth, depth)
    assert math.dist(point, offset) == pytest.approx(234.0, rel=1e-12)
    plain = depth_from_range(234.0, pixel, fx=FX, fy=FY, cx=CX, cy=CY)
    assert depth - plain == pytest.approx(0.25, abs=0.01)  # mostly the forward offset


def test_depth_rejects_an_impossible_range() -> None:
    with pytest.raises(InputError, match="cannot reach"):
        depth_from_range(-1.0, (CX, CY), fx=FX, fy=FY, cx=CX, cy=CY)


@pytest.mark.parametrize(
    "distance",
    ["1000000000.00", "1e100", "3_0_2.00", "1e300", "inf", "nan", "0x12C"],
)
def test_absurd_ranges_are_refused_by_the_parser(distance: str) -> None:
    # Sentences with valid checksums; before, each was stored and compared at -100 %.
    frame = trupulse_sentence(["PLTIT", "HV", "", "", "47.30", "D", "1.20", "D", distance, "M"])
    with pytest.raises(FrameError, match="not a number|beyond the TruPulse's 2000 m"):
        parse_trupulse(frame, 0.0)


def test_a_vectronix_range_beyond_any_module_is_refused() -> None:
    body = "LM,Md," + vectronix_range_field(30_000.0)
    with pytest.raises(FrameError, match="beyond the device's 0.5-25000 m"):
        parse_vectronix(vectronix_frame(body), 0.0)

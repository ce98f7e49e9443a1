"""The rangefinder driver on scripted bytes and the sim:// URL handler; the simulator core."""

from __future__ import annotations

import errno
import time
from collections import deque
from collections.abc import Sequence
from pathlib import Path

import pytest
import serial

from rigkit.errors import InputError
from rigkit.rangefinder import (
    DeviceError,
    LineStats,
    PortError,
    Rangefinder,
    ReadTimeout,
    encode_trupulse_hv,
    open_rangefinder,
    parse_trupulse,
    trupulse_sentence,
    vectronix_frame,
)
from rigkit.rangefinder.sim import (
    SimConfig,
    SimulatedTruPulse,
    SimulatedVectronix,
    make_device,
    parse_sim_url,
)

GOOD = b"$PLTIT,HV,301.90,M,47.30,D,1.20,D,302.00,M*5E\r\n"
OTHER = encode_trupulse_hv(234.0, inclination_deg=-2.0, azimuth_deg=10.0)
CORRUPT = GOOD.replace(b"*5E", b"*5F")
VECTRONIX_RESPONSE = vectronix_frame("LM,Md,v0029200,R000E301,R000E301")


class ScriptedPort:
    """A port that delivers scripted chunks (or raises scripted errors) in order.

    Each chunk "arrives" when the previous one has been read; once the script
    is used up, reads time out (return b"" after 10 ms), like a quiet line.
    """

    def __init__(self, script: Sequence[bytes | BaseException], name: str = "scripted") -> None:
        self.script: deque[bytes | BaseException] = deque(script)
        self.current = b""
        self.written = b""
        self.closed = False
        self.name = name

    @property
    def in_waiting(self) -> int:
        return len(self.current)

    def read(self, size: int = 1) -> bytes:
        if self.closed:
            raise serial.SerialException("port is closed")
        if not self.current:
            if not self.script:
                time.sleep(0.01)
                return b""
            item = self.script.popleft()
            if isinstance(item, BaseException):
                raise item
            self.current = item
        data, self.current = self.current[:size], self.current[size:]
        return data

    def write(self, data: bytes) -> int:
        if self.closed:
            raise serial.SerialException("port is closed")
        self.written += data
        return len(data)

    def reset_input_buffer(self) -> None:
        self.current = b""

    def close(self) -> None:
        self.closed = True


def scripted(
    script: Sequence[bytes | BaseException],
    protocol: str = "trupulse",
    log_path: Path | None = None,
) -> tuple[ScriptedPort, Rangefinder]:
    port = ScriptedPort(script)
    return port, open_rangefinder(port, protocol, timeout=0.3, log_path=log_path)


# -- line faults on scripted bytes -------------------------------------------------


def test_reading_survives_noise_and_a_partial_line_split_across_chunks() -> None:
    port, rf = scripted(
        [b"\xff\xfe\x00line noise", b"TIT,HV,1.0,M*00\r\n", GOOD[:17], GOOD[17:30], GOOD[30:]]
    )
    before = time.time()
    reading = rf.read()
    assert reading.slope_distance_m == pytest.approx(302.0)
    assert reading.horizontal_distance_m == pytest.approx(301.9)
    assert reading.raw == GOOD.rstrip()
    assert before <= reading.timestamp <= time.time()
    assert rf.stats.malformed == 2
    assert rf.stats.readings == 1


def test_bad_checksum_is_skipped_counted_and_never_returned() -> None:
    port, rf = scripted([CORRUPT, OTHER])
    reading = rf.read()
    assert reading.slope_distance_m == pytest.approx(234.0)
    assert rf.stats.bad_checksums == 1
    assert rf.stats.readings == 1


def test_only_bad_checksums_time_out_and_say_so() -> None:
    port, rf = scripted([CORRUPT, CORRUPT])
    with pytest.raises(ReadTimeout) as caught:
        rf.read()
    message = str(caught.value)
    assert message.startswith("no reading from scripted within 0.3 s")
    assert "2 bad checksums" in message
    assert "\n" not in message


def test_unknown_and_other_sentence_types_are_skipped() -> None:
    script = [
        trupulse_sentence(["PLTIT", "ZZ", "1"]),
        trupulse_sentence(["GPGGA", "123519"]),
        b"$PLTIT,HT,5.50,M*36\r\n",
        b"$PLTIT,HV,,,0.00,D,29.10,D,,*5D\r\n",
        GOOD,
    ]
    port, rf = scripted(script)
    assert rf.read().slope_distance_m == pytest.approx(302.0)
    assert (rf.stats.unknown, rf.stats.other, rf.stats.readings) == (2, 2, 1)


def test_silent_device_times_out_with_one_clear_line() -> None:
    port, rf = scripted([])
    started = time.monotonic()
    with pytest.raises(ReadTimeout) as caught:
        rf.read(timeout=0.2)
    assert 0.2 <= time.monotonic() - started < 1.0
    assert str(caught.value).startswith(
        "no reading from scripted within 0.2 s: nothing received (was it fired?)"
    )


def test_bytes_without_a_complete_frame_hint_at_the_baud_rate() -> None:
    port, rf = scripted([b"$\x13\x7f\x02junk", b"\x15\x0b"])
    with pytest.raises(ReadTimeout, match="no complete frame \\(wrong baud rate\\?\\)"):
        rf.read()


def test_cable_pulled_mid_read_raises_and_releases_the_port() -> None:
    pulled = serial.SerialException(
        "device reports readiness to read but returned no data (device disconnected?)"
    )
    port, rf = scripted([GOOD[:20], pulled])
    with pytest.raises(PortError) as caught:
        rf.read()
    assert str(caught.value).startswith("lost connection to scripted: device reports readiness")
    assert "port closed" in str(caught.value)
    assert port.closed and rf.closed
    with pytest.raises(PortError, match="scripted is closed"):
        rf.read()


def test_io_error_on_read_is_a_lost_connection() -> None:
    port, rf = scripted([OSError(errno.EIO, "Input/output error")])
    with pytest.raises(PortError, match="lost connection to scripted: .*Input/output error"):
        rf.read()
    assert port.closed


def test_write_failure_when_requesting_is_a_lost_connection() -> None:
    port, rf = scripted([])
    port.closed = True
    with pytest.raises(PortError, match="lost connection"):
        rf.read(trigger=True)


def test_raw_log_records_all_traffic(tmp_path: Path) -> None:
    log = tmp_path / "raw.txt"
    port, rf = scripted([b"\x00", GOOD], log_path=log)
    rf.read(trigger=True)
    rf.close()
    lines = log.read_text(encoding="ascii").splitlines()
    assert lines[0].endswith("-- opened scripted protocol=trupulse baud=4800 8N1")
    assert lines[1].split(" ", 1)[1] == "TX $GO\\r\\n"
    assert lines[2].split(" ", 1)[1] == "RX \\x00"
    received = "".join(line.split(" RX ", 1)[1] for line in lines if " RX " in line)
    assert received == "\\x00" + GOOD.decode().replace("\r\n", "\\r\\n")
    assert lines[-1].endswith("-- closed")


def test_trupulse_waits_for_the_shot_unless_triggered() -> None:
    port, rf = scripted([GOOD])
    rf.read()
    assert port.written == b""
    port, rf = scripted([GOOD])
    rf.read(trigger=True)
    assert port.written == b"$GO\r\n"


def test_stale_frames_are_dropped_before_a_request() -> None:
    port, rf = scripted([GOOD + OTHER])
    assert rf.read().slope_distance_m == pytest.approx(302.0)  # OTHER is now buffered
    port.script.append(GOOD)
    assert rf.read(trigger=True).slope_distance_m == pytest.approx(302.0)


# -- Vectronix request/response on scripted bytes ---------------------------------


def test_vectronix_requests_then_reads_the_response() -> None:
    port, rf = scripted([b"<", b">AC*84\r", VECTRONIX_RESPONSE + b"<"], "vectronix")
    reading = rf.read()
    assert port.written == b">LM,Md,3*D5\r"
    assert reading.slope_distance_m == pytest.approx(292.0)
    assert reading.unit == "cm"


@pytest.mark.parametrize(
    ("answer", "message"),
    [
        (b">NA,0*EB\r!", "rejected the command \\(NACK 0: message checksum error\\)"),
        (b">AC*84\r" + vectronix_frame("LM,Md,R000E301,R000E301,R000E301") + b"<", "no valid"),
        (b">AC*84\r!", "reported a failure"),
    ],
)
def test_vectronix_failures_are_device_errors(answer: bytes, message: str) -> None:
    port, rf = scripted([answer], "vectronix")
    with pytest.raises(DeviceError, match=f"^scripted: .*{message}"):
        rf.read()


def test_error_notices_do_not_raise_without_a_request() -> None:
    port, rf = scripted([b"!", VECTRONIX_RESPONSE], "vectronix")
    assert rf.read(trigger=False).slope_distance_m == pytest.approx(292.0)


# -- opening ------------------------------------------------------------------------


def test_missing_device_is_one_clear_line() -> None:
    with pytest.raises(PortError) as caught:
        open_rangefinder("/dev/nonexistent-rigkit-port", "trupulse")
    assert str(caught.value).startswith("cannot open /dev/nonexistent-rigkit-port: no such device")
    assert "\n" not in str(caught.value)


def test_permission_denied_suggests_the_dialout_group(monkeypatch: pytest.MonkeyPatch) -> None:
    def refuse(url: str, **kwargs: object) -> None:
        raise serial.SerialException(errno.EACCES, f"could not open port {url}: denied")

    monkeypatch.setattr(serial, "serial_for_url", refuse)
    with pytest.raises(PortError, match="cannot open /dev/ttyUSB0: permission denied .*dialout"):
        open_rangefinder("/dev/ttyUSB0")


def test_unknown_url_scheme_is_a_port_error() -> None:
    with pytest.raises(PortError, match="cannot open nosuch://x: .*protocol 'nosuch' not known"):
        open_rangefinder("nosuch://x")


@pytest.mark.parametrize(
    ("kwargs", "message"),
    [
        ({"protocol": "leica"}, "unknown rangefinder protocol 'leica'"),
        ({"timeout": 0}, "timeout must be positive"),
        ({"baud": -9600}, "baud rate must be positive"),
        ({"parity": "X"}, "parity must be one of"),
        ({"bytesize": 9}, "data bits"),
        ({"stopbits": 3}, "stop bits"),
    ],
)
def test_bad_settings_are_input_errors(kwargs: dict[str, object], message: str) -> None:
    with pytest.raises(InputError, match=message):
        open_rangefinder("sim://trupulse", **kwargs)  # type: ignore[arg-type]


def test_unwritable_raw_log_is_an_input_error(tmp_path: Path) -> None:
    with pytest.raises(InputError, match="--raw-log: cannot create .*missing"):
        open_rangefinder("sim://trupulse", log_path=tmp_path / "missing" / "raw.txt")


def test_line_stats_describe() -> None:
    stats = LineStats(frames=4, readings=1, bad_checksums=2, malformed=1)
    assert stats.describe() == "4 frames: 1 reading, 2 bad checksums, 1 malformed"
    assert stats.since(LineStats(frames=1, bad_checksums=2)).describe() == (
        "3 frames: 1 reading, 1 malformed"
    )


# -- the sim:// pyserial URL handler ------------------------------------------------


def test_sim_url_handler_delivers_trupulse_shots() -> None:
    with open_rangefinder("sim://trupulse?interval=0.02&distance=234&unit=Y", timeout=2) as rf:
        readings = [rf.read() for _ in range(3)]
    assert [r.unit for r in readings] == ["yd"] * 3
    assert all(abs(r.slope_distance_m - 234.0) < 0.05 for r in readings)
    assert rf.closed


def test_simulated_noise_replays_with_the_same_seed() -> None:
    def distances(seed: int) -> list[float]:
        url = f"sim://trupulse?interval=0.01&noise=0.5&seed={seed}"
        with open_rangefinder(url, timeout=2) as rf:
            return [rf.read().slope_distance_m for _ in range(4)]

    first = distances(7)
    assert first == distances(7)
    assert first != distances(8)
    assert len(set(first)) > 1


def test_simulated_faults_never_produce_a_bad_reading() -> None:
    url = "sim://trupulse?interval=0.01&garbage=0.5&bad_checksum=0.4&other=0.5&seed=3"
    with open_rangefinder(url, timeout=2) as rf:
        readings = [rf.read() for _ in range(8)]
        stats = rf.stats
    for reading in readings:
        assert reading.slope_distance_m == pytest.approx(302.0)
        assert parse_trupulse(reading.raw, reading.timestamp) == reading  # checksum was valid
    assert stats.bad_checksums > 0 and stats.malformed > 0
    assert stats.other + stats.unknown > 0


def test_simulated_silence_times_out() -> None:
    with (
        open_rangefinder("sim://trupulse?silent=1&interval=0.01", timeout=0.2) as rf,
        pytest.raises(ReadTimeout, match="nothing received"),
    ):
        rf.read()


def test_simulated_cable_pull_closes_the_port() -> None:
    rf = open_rangefinder("sim://trupulse?interval=0.01&disconnect_after=1", timeout=2)
    rf.read()
    with pytest.raises(PortError, match="simulated cable pull.*port closed"):
        rf.read()
    assert not rf.port.is_open  # type: ignore[attr-defined]


def test_sim_url_with_unknown_option_cannot_be_opened() -> None:
    with pytest.raises(PortError, match="cannot open sim://trupulse\\?nosie=1: unknown simulator"):
        open_rangefinder("sim://trupulse?nosie=1")


def test_sim_url_handler_serves_vectronix_requests() -> None:
    with open_rangefinder("sim://vectronix?distance=292&noise=0.02", "vectronix", timeout=2) as rf:
        readings = [rf.read() for _ in range(3)]
    assert all(abs(r.slope_distance_m - 292.0) < 0.2 for r in readings)
    assert len({r.raw for r in readings}) > 1
    assert rf.stats.other >= 3  # the acknowledgements


def test_simulated_vectronix_miss_is_a_device_error() -> None:
    with (
        open_rangefinder("sim://vectronix?miss=1", "vectronix", timeout=2) as rf,
        pytest.raises(DeviceError, match="no valid range"),
    ):
        rf.read()


# -- simulator core ---------------------------------------------------------------


def test_trupulse_core_fires_on_schedule_and_on_go() -> None:
    device = SimulatedTruPulse(SimConfig(interval=1.0), now=100.0)
    assert device.next_event() == 101.0
    assert device.output(100.9) == b""
    assert device.output(103.0).count(b"$PLTIT,HV") == 3
    device.receive(b"$G", 103.1)
    assert device.output(103.1) == b""
    device.receive(b"O\r\n", 103.2)
    shot = device.output(103.2)
    assert shot == encode_trupulse_hv(302.0, inclination_deg=1.2, azimuth_deg=47.3)
    device.receive(b"$PLTIT,RQ,ID\r\n$MM,0\r\n", 103.3)
    assert device.output(103.3) == trupulse_sentence(["PLTIT", "ID", "TP360", "SIM"])


def test_trupulse_core_without_interval_fires_only_on_request() -> None:
    device = SimulatedTruPulse(SimConfig(interval=0), now=0.0)
    assert device.next_event() is None
    assert device.output(1e6) == b""


def test_cable_pull_cuts_a_frame_in_half() -> None:
    device = SimulatedTruPulse(SimConfig(interval=1.0, disconnect_after=1), now=0.0)
    data = device.output(2.0)
    frame = encode_trupulse_hv(302.0, inclination_deg=1.2, azimuth_deg=47.3)
    assert data == frame + frame[: len(frame) // 2]
    assert device.disconnected and device.next_event() is None
    assert device.output(10.0) == b""


def test_vectronix_core_answers_like_the_manual() -> None:
    device = SimulatedVectronix(SimConfig(device="vectronix", distance=60.91), now=0.0)
    assert device.output(0.0) == b"<"
    device.receive(b">LM,Md,3*D5\r", 0.1)
    assert device.output(0.1) == (
        b">AC*84\r>LM,Md,v0006091,R000E301,R000E301*46\r<"  # the published transaction
    )


@pytest.mark.parametrize(
    ("command", "answer"),
    [
        (b">LM,Md,3*D6\r", b">NA,0*EB\r!"),
        (b">LM,Xx,3" + b"*" + b"%02X" % (sum(b"LM,Xx,3") % 256) + b"\r", b">NA,1*EC\r!"),
        (b">LM,Md,3,0*31\r", b">NA,2*ED\r!"),
        (b"hello\r", b""),
    ],
)
def test_vectronix_core_rejects_bad_commands(command: bytes, answer: bytes) -> None:
    device = SimulatedVectronix(SimConfig(device="vectronix"), now=0.0)
    device.output(0.0)
    device.receive(command, 0.1)
    assert device.output(0.1) == answer


def test_make_device_picks_the_protocol() -> None:
    assert isinstance(make_device(SimConfig(device="vectronix"), 0.0), SimulatedVectronix)
    assert isinstance(make_device(SimConfig(), 0.0), SimulatedTruPulse)


def test_parse_sim_url_reads_every_kind_of_option() -> None:
    config = parse_sim_url(
        "sim://TruPulse?distance=234&unit=f&silent=1&disconnect_after=3&seed=5&garbage=0.25"
    )
    assert config == SimConfig(
        distance=234.0, unit="F", silent=True, disconnect_after=3, seed=5, garbage=0.25
    )


@pytest.mark.parametrize(
    ("url", "message"),
    [
        ("loop://", "not a simulator URL"),
        ("sim://leica", "unknown simulated device 'leica'"),
        ("sim://trupulse?noise=loud", "bad value for simulator option noise: 'loud'"),
        ("sim://trupulse?silent=maybe", "bad value for simulator option silent"),
        ("sim://trupulse?garbage=1.5", "garbage is a probability"),
        ("sim://trupulse?distance=-3", "distance must be positive"),
        ("sim://trupulse?unit=K", "unit must be M, F or Y"),
        ("sim://trupulse?interval=-1", "interval must be >= 0"),
        ("sim://trupulse?disconnect_after=-1", "disconnect_after must be >= 0"),
        ("sim://vectronix?unit=F", "option unit does not apply to vectronix"),
    ],
)
def test_parse_sim_url_rejects_bad_urls(url: str, message: str) -> None:
    with pytest.raises(InputError, match=message):
        parse_sim_url(url)

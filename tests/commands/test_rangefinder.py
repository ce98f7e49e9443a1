"""``rigkit rangefinder read|log|simulate`` as a user runs them."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
from pathlib import Path

import pytest
import yaml

from rigkit.cli import main

REPO = Path(__file__).resolve().parents[2]
TRUPULSE = "sim://trupulse?interval=0.02"


def run(args: list[str], capsys: pytest.CaptureFixture[str]) -> tuple[int, str, str]:
    code = main(["rangefinder", *args])
    captured = capsys.readouterr()
    return code, captured.out, captured.err


def error_line(err: str) -> str:
    lines = err.splitlines()
    assert len(lines) == 1, err
    assert lines[0].startswith("rigkit rangefinder: error: ")
    return lines[0].removeprefix("rigkit rangefinder: error: ")


def test_read_json_prints_one_object(capsys: pytest.CaptureFixture[str]) -> None:
    code, out, err = run(["read", "--port", TRUPULSE, "--json", "--timeout", "2"], capsys)
    assert (code, err) == (0, "")
    lines = out.splitlines()
    assert len(lines) == 1
    data = json.loads(lines[0])
    assert data["slope_distance_m"] == pytest.approx(302.0)
    assert data["inclination_deg"] == pytest.approx(1.2)
    assert data["unit"] == "m" and data["protocol"] == "trupulse"
    assert data["raw"].startswith("$PLTIT,HV,")


def test_read_prints_a_human_line(capsys: pytest.CaptureFixture[str]) -> None:
    code, out, _ = run(["read", "--port", TRUPULSE + "&unit=F&low_quality=1"], capsys)
    assert code == 0
    assert out == (
        "slope 302.00 m, horizontal 301.93 m, inclination +1.20 deg, azimuth 47.30 deg "
        "(sent in ft; low-quality target)\n"
    )


def test_read_vectronix(capsys: pytest.CaptureFixture[str]) -> None:
    url = "sim://vectronix?distance=292"
    code, out, _ = run(["read", "--port", url, "--protocol", "vectronix", "--json"], capsys)
    assert code == 0
    assert json.loads(out)["slope_distance_m"] == pytest.approx(292.0)


def test_trigger_fires_a_device_nobody_is_holding(capsys: pytest.CaptureFixture[str]) -> None:
    url = "sim://trupulse?interval=0"
    code, out, _ = run(["read", "--port", url, "--trigger", "--timeout", "1"], capsys)
    assert code == 0 and out.startswith("slope 302.00 m")


def test_missing_port_is_one_line_and_exit_2(capsys: pytest.CaptureFixture[str]) -> None:
    code, out, err = run(["read", "--port", "/dev/nonexistent"], capsys)
    assert code == 2 and out == ""
    assert error_line(err).startswith("cannot open /dev/nonexistent: no such device")


def test_timeout_is_one_line_and_exit_2(capsys: pytest.CaptureFixture[str]) -> None:
    url = "sim://trupulse?silent=1"
    code, _, err = run(["read", "--port", url, "--timeout", "0.2"], capsys)
    assert code == 2
    assert error_line(err).startswith(f"no reading from {url} within 0.2 s")


def test_pulled_cable_is_one_line_and_exit_2(capsys: pytest.CaptureFixture[str]) -> None:
    url = TRUPULSE + "&disconnect_after=0"
    code, _, err = run(["read", "--port", url], capsys)
    assert code == 2
    assert error_line(err).startswith(f"lost connection to {url}")


def test_no_port_at_all(capsys: pytest.CaptureFixture[str]) -> None:
    code, _, err = run(["read"], capsys)
    assert code == 2
    assert error_line(err).startswith("no port: pass --port URL")


def test_raw_log_from_the_command_line(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    raw = tmp_path / "raw.txt"
    code, _, _ = run(["read", "--port", TRUPULSE, "--raw-log", str(raw)], capsys)
    assert code == 0
    text = raw.read_text(encoding="ascii")
    assert " RX " in text and "$PLTIT,HV," in text


def test_log_appends_json_lines(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    output = tmp_path / "laser.jsonl"
    for _ in range(2):
        code, out, err = run(
            ["log", "--port", TRUPULSE, "--output", str(output), "--count", "3", "--json"], capsys
        )
        assert code == 0
        assert len(out.splitlines()) == 3
        assert err.startswith(f"logged 3 readings to {output} (line: 3 frames: 3 readings)")
    lines = output.read_text(encoding="utf-8").splitlines()
    assert len(lines) == 6
    assert all(json.loads(line)["slope_distance_m"] == pytest.approx(302.0) for line in lines)


def test_log_requests_vectronix_at_the_interval(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    output = tmp_path / "laser.jsonl"
    args = ["log", "--port", "sim://vectronix", "--protocol", "vectronix", "--output", str(output)]
    code, _, err = run([*args, "--count", "2", "--interval", "0.5"], capsys)
    assert code == 0
    times = [json.loads(line)["timestamp"] for line in output.read_text().splitlines()]
    assert times[1] - times[0] >= 0.4  # paced, not back to back
    code, _, err = run([*args, "--interval", "0.1"], capsys)
    assert code == 2
    assert "--interval 0.1 is too short for vectronix" in error_line(err)


def test_log_stops_with_one_line_when_the_device_goes_quiet(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    output = tmp_path / "laser.jsonl"
    url = "sim://trupulse?interval=0.02&disconnect_after=2"
    code, out, err = run(["log", "--port", url, "--output", str(output)], capsys)
    assert code == 2
    assert len(out.splitlines()) == 2
    assert error_line(err).startswith(f"lost connection to {url}")
    assert len(output.read_text().splitlines()) == 2  # what arrived before is kept
    code, _, err = run(
        ["log", "--port", "sim://trupulse?silent=1", "--output", str(output), "--timeout", "0.2"],
        capsys,
    )
    assert code == 2
    assert error_line(err).startswith("no reading from sim://trupulse?silent=1 within 0.2 s")


def test_log_to_an_unwritable_file(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    target = tmp_path / "no-such-dir" / "laser.jsonl"
    code, _, err = run(["log", "--port", TRUPULSE, "--output", str(target)], capsys)
    assert code == 2
    assert error_line(err).startswith(f"--output: cannot create {target}")


def _rig_with(tmp_path: Path, rangefinder: dict[str, object]) -> Path:
    profile = yaml.safe_load((REPO / "rigs" / "vehicle-2m.yaml").read_text(encoding="utf-8"))
    profile["rangefinder"] = rangefinder
    path = tmp_path / "rig.yaml"
    path.write_text(yaml.safe_dump(profile), encoding="utf-8")
    return path


def test_port_protocol_and_baud_from_the_rig_profile(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    rig = _rig_with(tmp_path, {"protocol": "vectronix", "port": "sim://vectronix", "baud": 57600})
    raw = tmp_path / "raw.txt"
    code, out, _ = run(["read", "--rig", str(rig), "--json", "--raw-log", str(raw)], capsys)
    assert code == 0
    assert json.loads(out)["protocol"] == "vectronix"
    assert "protocol=vectronix baud=57600 8N1" in raw.read_text(encoding="ascii")


def test_flags_override_the_rig_profile(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    rig = _rig_with(tmp_path, {"protocol": "manual"})
    code, _, err = run(["read", "--rig", str(rig)], capsys)
    assert code == 2
    assert "rangefinder.protocol 'manual' is not read over serial" in error_line(err)
    code, out, _ = run(
        ["read", "--rig", str(rig), "--port", TRUPULSE, "--protocol", "trupulse"], capsys
    )
    assert code == 0 and out.startswith("slope 302.00 m")


@pytest.mark.parametrize("action", ["read", "log", "simulate"])
def test_each_subcommand_help_shows_an_example(
    action: str, capsys: pytest.CaptureFixture[str]
) -> None:
    with pytest.raises(SystemExit) as exited:
        main(["rangefinder", action, "--help"])
    assert exited.value.code == 0
    out = capsys.readouterr().out
    assert "examples:" in out and f"rigkit rangefinder {action}" in out


def test_simulate_help_lists_the_fault_options(capsys: pytest.CaptureFixture[str]) -> None:
    with pytest.raises(SystemExit):
        main(["rangefinder", "simulate", "--help"])
    out = capsys.readouterr().out
    for option in ("garbage", "bad_checksum", "silent", "disconnect_after", "seed"):
        assert f"  {option} " in out


def test_simulate_rejects_a_bad_url(capsys: pytest.CaptureFixture[str]) -> None:
    code, _, err = run(["simulate", "sim://trupulse?noise=x"], capsys)
    assert code == 2
    assert error_line(err) == "bad value for simulator option noise: 'x'"


def test_simulate_then_read_from_another_process(capsys: pytest.CaptureFixture[str]) -> None:
    env = {**os.environ, "PYTHONUNBUFFERED": "1"}
    process = subprocess.Popen(
        [sys.executable, "-m", "rigkit", "rangefinder", "simulate", "sim://trupulse?interval=0.05"],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        env=env,
        # Ctrl-C must reach it even when this suite was started as a background job,
        # which inherits SIGINT ignored (and Python then leaves it ignored).
        preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL),
    )
    try:
        assert process.stdout is not None
        path = process.stdout.readline().strip()
        assert path.startswith("/dev/")
        code, out, _ = run(["read", "--port", path, "--json", "--timeout", "5"], capsys)
        assert code == 0
        assert json.loads(out)["slope_distance_m"] == pytest.approx(302.0)
    finally:
        process.send_signal(signal.SIGINT)
        _, err = process.communicate(timeout=10)
    assert process.returncode == 0, err
    assert f"try: rigkit rangefinder read --port {path}" in err


def test_log_appends_to_nothing_but_a_log_of_readings(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """An image, or a raw log, given as --output is refused before the port opens and
    keeps its bytes; a log whose last line was cut short gets its next reading on a line
    of its own."""
    photo = tmp_path / "photo.png"
    photo.write_bytes(b"\x89PNG\r\n\x1a\n")
    code, _, err = run(["log", "--port", TRUPULSE, "--count", "1", "--output", str(photo)],
                       capsys)
    assert code == 2 and "is no log rigkit started" in error_line(err)
    assert photo.read_bytes() == b"\x89PNG\r\n\x1a\n"
    raw = tmp_path / "raw.txt"  # a log of rigkit's, but of the serial traffic
    assert run(["read", "--port", TRUPULSE, "--raw-log", str(raw)], capsys)[0] == 0
    code, _, err = run(["log", "--port", TRUPULSE, "--count", "1", "--output", str(raw)],
                       capsys)
    assert code == 2 and "holds something other than readings" in error_line(err)
    same = tmp_path / "both.jsonl"
    code, _, err = run(["log", "--port", TRUPULSE, "--count", "1", "--output", str(same),
                        "--raw-log", str(same)], capsys)
    assert code == 2 and "also --raw-log" in error_line(err) and not same.exists()
    fifo = tmp_path / "fifo.jsonl"
    os.mkfifo(fifo)  # opened, it would block the command until someone read it
    code, _, err = run(["log", "--port", TRUPULSE, "--count", "1", "--output", str(fifo)],
                       capsys)
    assert code == 2 and "is a FIFO, not a log rigkit may append to" in error_line(err)
    log = tmp_path / "laser.jsonl"
    assert run(["log", "--port", TRUPULSE, "--count", "1", "--output", str(log)], capsys)[0] == 0
    with log.open("a") as torn:
        torn.write('{"slope_dist')  # stopped mid-line
    code, _, _ = run(["log", "--port", TRUPULSE, "--count", "1", "--output", str(log)], capsys)
    lines = log.read_text(encoding="utf-8").splitlines()
    assert code == 0 and len(lines) == 3 and lines[1] == '{"slope_dist'
    assert json.loads(lines[2])["slope_distance_m"] == pytest.approx(302.0)

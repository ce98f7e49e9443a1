"""``rigkit process --scheduler``: sessions as tasks on a Dask distributed cluster (a
local one here), failures per session, and a scheduler that cannot be used."""

from __future__ import annotations

import socket
import sys
import time
from pathlib import Path

import pytest

from rigkit.capture.comparisons import LOG_NAME, read_rows
from rigkit.cli import main
from tests.conftest import copy_session

distributed = pytest.importorskip("distributed")


@pytest.mark.slow
def test_sessions_run_as_tasks_on_a_cluster(
    small_session: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    a, b = (copy_session(small_session, tmp_path, name) for name in ("a", "b"))
    broken = copy_session(small_session, tmp_path, "broken",
                          edit=lambda data: data["frames"].pop("back"))
    with distributed.LocalCluster(n_workers=1, threads_per_worker=1, processes=False,
                                  protocol="tcp", host="127.0.0.1",
                                  dashboard_address=None) as cluster:
        code = main(["process", str(a), str(b), str(broken), "--scheduler",
                     cluster.scheduler_address, "--quiet"])
    captured = capsys.readouterr()
    assert code == 1
    assert "on the 1 worker(s) of tcp://127.0.0.1:" in captured.err
    assert "2 processed, 1 failed" in captured.out
    assert f"FAILED {broken}: no back frame" in captured.out
    assert f"    ok {a} (" in captured.err and f"    ok {b} (" in captured.err
    # The same per-session work as the local pool: results, the log, one run id.
    for session in (a, b):
        assert (session / "results" / "depth.npy").is_file()
        assert not list(session.glob(".results*"))
    run_ids = {row.run_id for s in (a, b) for row in read_rows(s / LOG_NAME)}
    assert len(run_ids) == 1
    assert "FAILED: " in (broken / "history.log").read_text()


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


def test_an_unreachable_scheduler_fails_fast_with_one_line(
    small_session: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    monkeypatch.setattr("rigkit.batch.cluster.CONNECT_TIMEOUT_S", 1.0)
    address = f"tcp://127.0.0.1:{_free_port()}"
    t0 = time.monotonic()
    assert main(["process", str(small_session), "--scheduler", address]) == 2
    assert time.monotonic() - t0 < 5
    err = capsys.readouterr().err.strip()
    assert f"--scheduler {address}: cannot reach the scheduler" in err
    assert len(err.splitlines()) == 1


def test_a_scheduler_without_workers(
    small_session: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    monkeypatch.setattr("rigkit.batch.cluster.WORKER_WAIT_S", 0.5)
    with distributed.LocalCluster(n_workers=0, processes=False,
                                  dashboard_address=None) as cluster:
        assert main(["process", str(small_session), "--scheduler",
                     cluster.scheduler_address]) == 2
    assert "no worker joined within 0.5 s (start one: dask worker" in capsys.readouterr().err


def test_without_distributed_it_says_which_extra(
    small_session: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    monkeypatch.setitem(sys.modules, "distributed", None)  # import fails
    assert main(["process", str(small_session), "--scheduler", "tcp://127.0.0.1:8786"]) == 2
    assert "pip install 'rigkit[cluster]'" in capsys.readouterr().err


@pytest.mark.slow
def test_a_session_gives_the_same_results_locally_and_on_a_cluster(tmp_path: Path) -> None:
    """Bit for bit, whatever BLAS threads each side has (issue 34: a local run and
    Dask's one-thread workers gave depth maps 85 pixels apart, one by 14.5 m). A field
    scene with a lens: its lens fit is where the thread count used to show."""
    from dataclasses import replace

    from threadpoolctl import threadpool_limits

    from rigkit.batch import run_batch
    from rigkit.batch.cluster import run_on_cluster
    from rigkit.synth import SynthParams, generate_scene
    from rigkit.synth.scene import field_params
    from rigkit.synth.session import write_synthetic_session

    params = replace(field_params(SynthParams(width=480, height=360)),
                     distortion=(0.47, 0.0, 0.0, 0.0, 0.0))
    local = tmp_path / "local"
    write_synthetic_session(generate_scene(params, seed=3), local, n_targets=4, seed=3)
    remote = copy_session(local, tmp_path, "remote")
    with threadpool_limits(limits=1, user_api="blas"):  # as Dask's worker processes have
        [outcome] = run_batch([local], jobs=1, run_id="20260101T000000Z-0001")
    assert outcome.ok, outcome.message
    with (distributed.LocalCluster(n_workers=1, threads_per_worker=1, processes=False,
                                   dashboard_address=None) as cluster,
          distributed.Client(cluster) as client,
          threadpool_limits(limits=2, user_api="blas")):
        [outcome] = run_on_cluster([remote], client, run_id="20260101T000000Z-0001")
    assert outcome.ok, outcome.message
    for name in ("depth.npy", "sigma.npy"):
        assert (local / "results" / name).read_bytes() == (remote / "results" / name
                                                           ).read_bytes(), name
    rows = [[replace(r, time_utc="") for r in read_rows(s / LOG_NAME)] for s in (local, remote)]
    assert rows[0] == rows[1] and len(rows[0]) == 4


def _fake_service(answer: bytes | None) -> tuple[str, socket.socket]:
    """A TCP port that accepts and then stays silent (None) or sends ``answer``."""
    import threading

    server = socket.socket()
    server.bind(("127.0.0.1", 0))
    server.listen(8)

    def serve() -> None:
        while True:
            try:
                conn, _ = server.accept()
            except OSError:
                return
            if answer is not None:
                conn.sendall(answer)

    threading.Thread(target=serve, daemon=True).start()
    return f"tcp://127.0.0.1:{server.getsockname()[1]}", server


@pytest.mark.parametrize("answer", [None, b"\xff" * 64 + b"HTTP/1.1 200 OK\r\n\r\n" * 8])
def test_a_port_that_is_no_scheduler_is_one_line_in_time(
    small_session: Path, answer: bytes | None, monkeypatch: pytest.MonkeyPatch,
    capsys: pytest.CaptureFixture[str]
) -> None:
    monkeypatch.setattr("rigkit.batch.cluster.CONNECT_TIMEOUT_S", 1.0)
    address, server = _fake_service(answer)
    with server:
        t0 = time.monotonic()
        assert main(["process", str(small_session), "--scheduler", address]) == 2
        assert time.monotonic() - t0 < 4
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and f"--scheduler {address}: " in err
    assert ("no Dask scheduler answered within 1 s" if answer is None
            else "cannot reach the scheduler") in err


@pytest.mark.slow
def test_a_session_runs_once_per_run_whatever_the_cluster_retries(
    small_session: Path, tmp_path: Path
) -> None:
    from rigkit.batch.cluster import run_on_cluster

    session = copy_session(small_session, tmp_path)
    missing = tmp_path / "not-there"
    run_id = "20260101T000000Z-0001"
    with (distributed.LocalCluster(n_workers=1, threads_per_worker=1, processes=False,
                                   dashboard_address=None) as cluster,
          distributed.Client(cluster) as client):
        first = run_on_cluster([session, missing], client, run_id=run_id)
        again = run_on_cluster([session], client, run_id=run_id)  # a task run again
    assert first[0].ok and again[0].ok and "already processed in run" in again[0].message
    rows = read_rows(session / LOG_NAME)
    assert len(rows) == 5 and {r.run_id for r in rows} == {run_id}
    assert not first[1].ok
    assert "no such session folder (on worker inproc://" in first[1].message
    assert "with the path as that worker sees it" in first[1].message

"""A frame arriving in ``rigkit field``: staged, hashed and decoded once, and every check
of it (the burst comparison, the add, the on-site checks and the preview beside them)
runs on that one decoding (rigkit.capture.field.ingest, rigkit.capture.views.admit)."""

from __future__ import annotations

import hashlib
from collections import Counter
from pathlib import Path

import cv2
import numpy as np
import pytest

from rigkit.capture import load_session
from rigkit.capture.field import frames_at
from rigkit.core import files
from rigkit.imagefile import decode
from rigkit.synth.demo import Demo
from tests.tui.conftest import opened, synchronous, text, wait_for, write_frame
from tests.tui.test_flow import SIZE, take_the_left_frame, watching_app


def _count(monkeypatch: pytest.MonkeyPatch) -> tuple[Counter[str], Counter[str]]:
    """Decodings (of an image file's bytes) and whole-file hashings (core.files.file_sha256),
    counted by the SHA-256 of what was decoded or hashed."""
    decoded: Counter[str] = Counter()
    hashed: Counter[str] = Counter()
    real_decode, real_hash = decode._decode, files.file_sha256

    def counting_decode(path: Path, data: bytes) -> np.ndarray:
        decoded[hashlib.sha256(data).hexdigest()] += 1
        return real_decode(path, data)

    def counting_hash(path: Path) -> str:
        digest = real_hash(path)
        hashed[digest] += 1
        return digest

    monkeypatch.setattr(decode, "_decode", counting_decode)
    for module in ("rigkit.core.files", "rigkit.capture.actions", "rigkit.capture.frames"):
        monkeypatch.setattr(f"{module}.file_sha256", counting_hash)
    return decoded, hashed


@pytest.mark.slow
@synchronous
async def test_a_burst_frame_arriving_is_decoded_once_for_all_its_checks(
        demo: Demo, tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """Before: a PNG burst frame was checked twice, hashed twice and decoded three times
    before its checks showed (the burst comparison, the add, the on-site checks)."""
    session, app = watching_app(demo)
    left = cv2.imread(str(demo.scene / "left.png"), cv2.IMREAD_UNCHANGED)
    noise = np.random.default_rng(5).integers(-2, 3, left.shape)
    second = tmp_path / "second.png"  # another exposure of the same view
    cv2.imwrite(str(second), np.clip(left.astype(int) + noise, 0, 255).astype(left.dtype))
    async with app.run_test(size=SIZE) as pilot:
        await opened(pilot, app)
        await take_the_left_frame(pilot, app, demo)
        decoded, hashed = _count(monkeypatch)
        write_frame(demo.card / "DSCN0002.PNG", second)
        await wait_for(pilot, lambda: len(frames_at(load_session(session), "left")) == 2,
                       "the second frame of the burst")
        await wait_for(pilot, lambda: "shimmer" in text(app, "#checks"), "its checks")
    sha = frames_at(load_session(session), "left")[1].sha256
    assert decoded[sha] == 1, decoded
    assert hashed[sha] == 0, hashed  # hashed as it was staged, not read again to hash it

"""A capture's frames as the pipeline's grey images: decoded, checked, stacked.

Every way into the depth method (``rigkit depth``, ``rigkit process``, ``rigkit
field``) reads frames here, so a frame is decoded and judged the same way whichever
command reads it:

* each file is decoded (RAW through LibRaw, never an embedded preview) and must hold
  a picture (:func:`rigkit.imagefile.rawio.load_linear_grey`);
* the set must make a capture (:func:`capture_problems`): every position present, no
  file at two positions or twice in a burst, RAW not mixed with ordinary images;
* every frame must have the size of the others and of the rig, checked on its header
  before it is decoded (:func:`rigkit.imagefile.imagesize.check_size`);
* a position's burst is aligned and median-stacked, and the heat shimmer between the
  first two frames of the first burst is measured;
* the three images are brought to one brightness scale.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from concurrent.futures import Future, ThreadPoolExecutor
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from rigkit.capture.model import POSITIONS
from rigkit.core.files import file_sha256
from rigkit.errors import InputError
from rigkit.imagefile.imagesize import check_size
from rigkit.imagefile.rawio import is_raw, load_linear_grey, to_pipeline
from rigkit.pipeline.burst import stack_burst
from rigkit.pipeline.shimmer import Shimmer, burst_shimmer

DECODERS = 2
"""Worker threads decoding frames, side by side, and frames decoded ahead."""


@dataclass(frozen=True)
class FrameFile:
    """One frame of a capture: its file and, where known, the SHA-256 of its bytes (hex;
    a session records it at ingest, and it names the frame's decoded copy in a cache);
    ``name`` is how messages show it (a session's ``raw/...``; default: the path)."""

    path: Path
    sha256: str | None = None
    name: str = ""

    @property
    def shown(self) -> str:
        return self.name or str(self.path)


@dataclass(frozen=True)
class LoadedCapture:
    """The three positions ready for the pipeline: ``images`` left, right, back, each
    (H, W) float32 grey in [0, 255] on one scale; ``size`` (W, H) px; ``shimmer`` the
    heat shimmer measured between the first two frames of the first burst and which
    they were (None for single frames); ``linear`` whether they came from RAW."""

    images: tuple[np.ndarray, np.ndarray, np.ndarray]
    size: tuple[int, int]
    shimmer: tuple[Shimmer, str] | None
    linear: bool


def frame_files(bursts: Mapping[str, Sequence[Path]]) -> dict[str, tuple[FrameFile, ...]]:
    """Frames named by hand (position -> files), hashed where two files have the same
    size: only those can be copies of each other, so a frame given twice is caught
    without reading every file twice."""
    every = [Path(p) for paths in bursts.values() for p in paths]
    sizes: dict[int, int] = {}
    for path in every:
        if path.is_file():
            size = path.stat().st_size
            sizes[size] = sizes.get(size, 0) + 1
    def frame(path: Path) -> FrameFile:
        shared = path.is_file() and sizes[path.stat().st_size] > 1
        return FrameFile(path, file_sha256(path) if shared else None)

    return {pos: tuple(frame(Path(p)) for p in paths) for pos, paths in bursts.items()}


def capture_problems(bursts: Mapping[str, Sequence[FrameFile]], complete: bool = True
                     ) -> list[str]:
    """Why these frames (position -> its burst) do not make a capture, one phrase
    each: a position without a frame (when the capture should be ``complete``), one
    file at two positions or twice in a burst (same path, or same content where hashes
    are known), RAW mixed with ordinary image files."""
    problems = [f"no {pos} frame" for pos in POSITIONS if complete and not bursts.get(pos)]
    seen: dict[object, tuple[str, FrameFile]] = {}
    for position in POSITIONS:
        for frame in bursts.get(position, ()):
            for key in _identities(frame):
                if key in seen:
                    where, first = seen[key]
                    twice = "twice in the burst" if where == position else \
                        f"for {where} and {position}"
                    problems.append(f"{frame.shown} is the same file as {first.shown}, "
                                    f"given {twice}: every frame must be its own exposure")
                    break
            else:
                seen.update(dict.fromkeys(_identities(frame), (position, frame)))
    every = [f for pos in POSITIONS for f in bursts.get(pos, ())]
    kinds = {is_raw(f.path) for f in every}
    if len(kinds) > 1:
        raw = next(f for f in every if is_raw(f.path))
        plain = next(f for f in every if not is_raw(f.path))
        problems.append(f"RAW frames ({raw.shown}) mixed with ordinary images "
                        f"({plain.shown}): their brightness cannot be matched; take all "
                        "three positions in one format")
    return problems


def _identities(frame: FrameFile) -> list[object]:
    """What makes two frames the same file: the resolved path, and the content hash."""
    keys: list[object] = [("path", frame.path.resolve())]
    if frame.sha256:
        keys.append(("sha256", frame.sha256))
    return keys


def load_capture(
    bursts: Mapping[str, Sequence[FrameFile]],
    resolution: tuple[int, int] | None = None,
    cache_dir: Path | None = None,
    rig_name: str = "rig profile",
    size_from: str | None = None,
) -> LoadedCapture:
    """Decode, check and stack a capture's frames (module docstring). ``resolution``
    (W, H) is the rig's image size (None: the frames only have to agree); ``cache_dir``
    keeps decoded RAW frames by content hash; ``size_from`` says whose size
    ``resolution`` is in messages ("the left frame a.png is"; default the ``rig_name``'s).
    InputError names the first problem, in the order of the positions and their frames.

    The next position's frames are decoded in worker threads while this one's are
    stacked (a 5-frame burst per position at 16 MP: 5.4 s -> about 3 s on two cores),
    and single frames two positions at once; the decoders run side by side
    (:func:`rigkit.core.chatter.attributed`: a complaint printed meanwhile is
    checked by decoding that frame again, alone)."""
    problems = capture_problems(bursts)
    if problems:
        raise InputError("; ".join(problems))
    linear = is_raw(bursts["left"][0].path)
    expected, whose = resolution, size_from or f"the {rig_name} is for"
    greys, shimmer = [], None
    pool = ThreadPoolExecutor(max_workers=DECODERS, thread_name_prefix="rigkit-decode")

    def decode(position: str) -> list[tuple[FrameFile, Future[np.ndarray]]]:
        return [(frame, pool.submit(load_linear_grey, frame.path, cache_dir, frame.sha256,
                                    resolution, whose))
                for frame in bursts[position]]

    upcoming = iter(POSITIONS)
    queued: dict[str, list[tuple[FrameFile, Future[np.ndarray]]]] = {}

    def top_up() -> None:
        """The next positions' frames decoded ahead while fewer than DECODERS frames are
        on their way (single frames: two positions at once)."""
        while (sum(map(len, queued.values())) < DECODERS
               and (position := next(upcoming, None)) is not None):
            queued[position] = decode(position)

    try:
        top_up()
        for position in POSITIONS:
            frames = []
            for frame, decoded in queued.pop(position):
                grey = decoded.result()
                if expected is None:  # without a rig's size, the first frame's
                    expected = (grey.shape[1], grey.shape[0])
                    whose = f"the {position} frame {frame.shown} is"
                check_size(frame.path, (grey.shape[1], grey.shape[0]), expected, whose)
                frames.append(grey)
            top_up()
            if shimmer is None and len(frames) > 1:
                shimmer = burst_shimmer(to_pipeline(frames[:2], linear=linear), position)
            greys.append(stack_burst(frames, f"{position} burst"))
    finally:
        pool.shutdown(wait=True, cancel_futures=True)
    left, right, back = to_pipeline(greys, linear=linear, overwrite=True)  # ours alone
    return LoadedCapture((left, right, back), (left.shape[1], left.shape[0]), shimmer, linear)

"""Small sessions with hand-made results for the export tests (no pipeline run), and a
PLY reader written for the tests (numpy only)."""

from __future__ import annotations

import math
from pathlib import Path

import cv2
import numpy as np

from rigkit.capture import LaserReading, add_target, create_session, load_session
from rigkit.capture.positioning import set_tripod_position
from rigkit.capture.tripod import TripodPosition, enu_direction
from tests.conftest import make_record, rig_file

SIZE = (400, 300)
"""(width, height) px: rigs/synthetic.yaml's 6 x 4.5 degree view at 400 px."""
TRIPOD = TripodPosition(46.55, 7.98, 1012.0, "manual", "2026-04-12T08:00:00Z")


def depth_plane(size: tuple[int, int] = SIZE) -> np.ndarray:
    """(H, W) float32 m: a slanted surface 280-320 m away, the top-left corner NaN (sky)."""
    width, height = size
    v, u = np.mgrid[0:height, 0:width].astype(np.float64)
    depth = (300.0 + 40.0 * (u / width - 0.5) - 10.0 * (v / height - 0.5)).astype(np.float32)
    depth[:10, :20] = np.nan
    return depth


def write_results(session: Path, depth: np.ndarray, run_id: str = "20260412T090000Z-0001",
                  flags: np.ndarray | None = None) -> None:
    """A results/ folder as rigkit process writes it, for ``depth`` (sigma 1 % of depth,
    grey a ramp; ``flags.npy`` only if given, as before rigkit wrote it)."""
    results = session / "results"
    results.mkdir()
    np.save(results / "depth.npy", depth)
    if flags is not None:
        np.save(results / "flags.npy", flags)
    np.save(results / "sigma.npy", (0.01 * depth).astype(np.float32))
    grey = (np.arange(depth.size) % 256).astype(np.uint8).reshape(depth.shape)
    cv2.imwrite(str(results / "grey.png"), grey)
    height, width = depth.shape
    camera = load_session(session).rig().intrinsics((width, height))
    record = make_record(load_session(session), run_id=run_id,
                         image_size_px=(width, height),
                         left_camera_px=(camera.focal_px, camera.cx_px, camera.cy_px))
    (results / "depth.json").write_text(record.to_json())


def new_session(folder: Path, name: str = "geo", depth: np.ndarray | None = None,
                flags: np.ndarray | None = None) -> Path:
    """A session on rigs/synthetic.yaml at :data:`SIZE` with results of ``depth``."""
    path = folder / name
    create_session(path, rig_file(folder, SIZE))
    write_results(path, depth_plane() if depth is None else depth, flags=flags)
    return path


def ground_depth(rotation: np.ndarray, below_m: float, f: float) -> np.ndarray:
    """(H, W) float32 m: the depth of flat ground ``below_m`` under the camera (an
    east-north plane of the tripod's local frame) for a camera oriented by ``rotation``
    (camera -> ENU), NaN where a pixel's ray does not go down to it."""
    width, height = SIZE
    v, u = np.mgrid[0:height, 0:width].astype(np.float64)
    rays = np.stack([(u - (width - 1) / 2) / f, (v - (height - 1) / 2) / f, np.ones_like(u)],
                    axis=-1)
    down = -(rays @ rotation.T)[..., 2]
    with np.errstate(divide="ignore", invalid="ignore"):
        depth = np.where(down > 0, below_m / down, np.nan)
    return depth.astype(np.float32)


def camera_orientation(azimuth: float, elevation: float, roll: float) -> np.ndarray:
    """R (3, 3), camera -> ENU, for a camera looking ``azimuth`` degrees from north and
    ``elevation`` up, rolled by ``roll`` degrees (right side down)."""
    forward = enu_direction(azimuth, elevation)
    right = np.array([math.cos(math.radians(azimuth)), -math.sin(math.radians(azimuth)), 0.0])
    down = np.cross(forward, right)
    r = math.radians(roll)
    right, down = (math.cos(r) * right + math.sin(r) * down,
                   -math.sin(r) * right + math.cos(r) * down)
    return np.column_stack([right, down, forward])


def laser_sighting(rotation: np.ndarray, pixel: tuple[float, float], depth_m: float,
                   f: float) -> tuple[float, float, float]:
    """(range m, azimuth deg, inclination deg) a laser at the camera reads for the point
    at ``depth_m`` on ``pixel``'s ray, the camera oriented by ``rotation``."""
    cx, cy = (SIZE[0] - 1) / 2, (SIZE[1] - 1) / 2
    point = depth_m * np.array([(pixel[0] - cx) / f, (pixel[1] - cy) / f, 1.0])
    east, north, up = rotation @ point
    distance = float(np.linalg.norm(point))
    return (distance, math.degrees(math.atan2(east, north)) % 360,
            math.degrees(math.asin(up / distance)))


def georeferenced_session(folder: Path, rotation: np.ndarray,
                          pixels: list[tuple[int, int]], errors_deg: list[float], *,
                          depth: np.ndarray | None = None, tripod: TripodPosition = TRIPOD,
                          flags: np.ndarray | None = None) -> Path:
    """A session with the tripod at ``tripod`` and a typed target at each pixel whose
    laser azimuth and inclination are off by ``errors_deg`` (one per target); results
    ``depth`` (default :func:`depth_plane`)."""
    depth = depth_plane() if depth is None else depth
    path = new_session(folder, depth=depth, flags=flags)
    set_tripod_position(path, tripod)
    f = load_session(path).rig().focal_px
    for i, ((u, v), error) in enumerate(zip(pixels, errors_deg, strict=True)):
        distance, azimuth, inclination = laser_sighting(rotation, (u, v), float(depth[v, u]), f)
        reading = LaserReading(distance, "2026-04-12T08:10:00Z", "manual",
                               inclination - error, azimuth_deg=(azimuth + error) % 360)
        add_target(load_session(path), f"T{i + 1}", (u, v), readings=[reading])
    return path


def read_ply(path: Path) -> np.ndarray:
    """A binary little-endian PLY's vertices as a structured array (a reader of our own:
    the header's element vertex and its scalar properties)."""
    data = path.read_bytes()
    end = data.index(b"end_header\n") + len(b"end_header\n")
    header = data[:end].decode("ascii").splitlines()
    assert header[:2] == ["ply", "format binary_little_endian 1.0"]
    types = {"float": "<f4", "double": "<f8", "uchar": "u1", "int": "<i4"}
    count = next(int(line.split()[2]) for line in header if line.startswith("element vertex"))
    fields = [(line.split()[2], types[line.split()[1]]) for line in header
              if line.startswith("property ")]
    vertices = np.frombuffer(data, np.dtype(fields), count=count, offset=end)
    assert end + vertices.nbytes == len(data)
    return vertices

"""The bundled example, processed once in a copy and exported: every format, and on the
map against its rendered truth. The example is a distorting scene (k1 0.47) placed at
46.55 N 7.98 E, its camera looking down on its slope (rigkit.synth.placement): the LAS
points and the DSM's cells must lie where the truth is, within their stated sigma, in
the tripod's UTM zone and in Swiss LV95; the truth is placed on the map apart from
rigkit's georeferencing (rigkit.synth.placement.true_map_points: numpy to geocentric,
PROJ to the grid)."""

from __future__ import annotations

import csv
import json
import math
import re
import shutil
from pathlib import Path

import laspy
import numpy as np
import pyproj
import pytest
import rasterio
import tifffile
from rasterio.errors import NotGeoreferencedWarning

from rigkit.cli import main
from rigkit.export.source import open_depth
from rigkit.rangefinder.ranging import range_on_ray
from rigkit.synth import load_scene
from rigkit.synth.placement import Placement, gridded_truth, sight_errors
from tests.export.helpers import read_ply

EXAMPLE = Path(__file__).resolve().parents[2] / "capture" / "example"
PLACEMENT = Placement(46.55123, 7.98456, 1012.0, 47.3, -50.0, 0.0, 49.6)
"""How the example was placed (rigkit.synth.placement.place_session: its tripod and
laser directions say so; the fit must find its pointing)."""


@pytest.fixture(scope="module")
def example(tmp_path_factory: pytest.TempPathFactory) -> Path:
    session = tmp_path_factory.mktemp("example") / "example"
    shutil.copytree(EXAMPLE, session)
    assert main(["process", str(session), "--quiet"]) == 0
    return session


@pytest.mark.slow
def test_the_bundled_example_as_ply_las_laz_and_tif(
    example: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """Exported from a fresh copy: every format holds every estimated pixel, on the map
    (the example has a tripod position and its targets' laser directions), and the
    points' median z is the depth map's."""
    out = tmp_path / "cloud"
    assert main(["export", str(example), "--out", str(out), "--format", "ply,las,laz,tif",
                 "--frame", "camera", "--quiet"]) == 0
    depth = np.load(example / "results" / "depth.npy")
    finite = depth[np.isfinite(depth)]
    printed = capsys.readouterr().out
    assert f"{finite.size} points (" in printed and f"median z {np.median(finite):.2f} m" in (
        printed)
    ply = read_ply(out / "example.ply")
    assert len(ply) == finite.size
    assert np.median(ply["z"]) == pytest.approx(np.median(finite), abs=1e-4)
    for name in ("example.las", "example.laz"):
        las = laspy.read(out / name)
        assert las.header.point_count == finite.size and las.header.parse_crs() is None
        assert np.median(las.z) == pytest.approx(np.median(finite), abs=1e-3)
        assert np.allclose(las.x, ply["x"], atol=1e-3) and np.array_equal(las.red // 257,
                                                                          ply["red"])
        assert np.allclose(las.sigma, ply["sigma"])
        # One return per pixel: LAS 1.4 readers refuse return number 0.
        assert set(las.return_number) == {1} and set(las.number_of_returns) == {1}
    with tifffile.TiffFile(out / "example.tif") as tif:  # the image's grid: its tags
        page = tif.pages[0]
        assert page.compression == 8 and page.tags[42113].value == "nan"  # DEFLATE, nodata
        assert json.loads(page.description)["rig"] == "synthetic-seed-7"
    with pytest.warns(NotGeoreferencedWarning), rasterio.open(out / "example.tif") as raster:
        assert math.isnan(raster.nodata) and raster.crs is None and raster.count == 2
        assert np.array_equal(raster.read(1), depth, equal_nan=True)
    assert sorted(p.name for p in out.iterdir()) == [  # and the ledger of what rigkit wrote
        ".rigkit-outputs", "example.export.json", "example.las", "example.laz", "example.ply",
        "example.tif"]
    # And on the map by default, from a fresh clone's example: no step of the user's.
    assert main(["export", str(example), "--out", str(tmp_path / "map"), "--format", "las",
                 "--step", "4", "--quiet"]) == 0
    assert "frame EPSG:32632 (WGS 84 / UTM zone 32N)" in capsys.readouterr().out


def _truth_on_map(example: Path, crs: pyproj.CRS, step: int) -> tuple[np.ndarray, ...]:
    """For the exported grid's estimated pixels (row-major, as the points come): the
    true points on ``crs`` (E, N, height as recorded: the GPS's mean sea level), the
    unit line of sight from the tripod on the map, the points' stated sigma along it,
    and where the truth has a surface."""
    from rigkit.synth.placement import true_map_points

    depth = np.load(example / "results" / "depth.npy")[::step, ::step]
    sigma = np.load(example / "results" / "sigma.npy")[::step, ::step]
    rows, cols = np.nonzero(np.isfinite(depth))
    pixels = np.column_stack([cols * step, rows * step]).astype(np.float64)
    points, line = true_map_points(load_scene(example), PLACEMENT, pixels, crs)
    rays = load_scene(example).cameras["left"].rays(pixels[:, 0], pixels[:, 1])
    stated = sigma[rows, cols] * np.linalg.norm(rays, axis=1)
    return points, line, stated, np.isfinite(points[:, 2])


def _within(ratio: np.ndarray) -> tuple[float, float, float]:
    """Shares within 1, 2 and 3 sigma."""
    return tuple(float((ratio <= k).mean()) for k in (1, 2, 3))  # type: ignore[return-value]


@pytest.mark.slow
@pytest.mark.parametrize("epsg", [32632, 2056])
def test_las_points_and_dsm_cells_agree_with_the_truth_within_their_sigma(
    example: Path, tmp_path: Path, epsg: int
) -> None:
    """UTM zone 32N (the default) and Swiss LV95 (--crs EPSG:2056): each LAS point lies
    within its sigma of its true point along the line of sight, as often as a Gaussian
    error would at least (68 %, 95 %, 99 % within 1, 2, 3 sigma), and within 5 mm across
    it (exact laser directions; a pinhole back-projection of this lens would be 2 cm
    off at the corners); each DSM cell within its sigma of the truth gridded alike."""
    step = 2
    out = tmp_path / "out"
    crs_args = [] if epsg == 32632 else ["--crs", f"EPSG:{epsg}"]
    assert main(["export", str(example), "--out", str(out), "--format", "las,dsm", "--step",
                 str(step), "--quiet", *crs_args]) == 0
    las = laspy.read(out / "example.las")
    crs = las.header.parse_crs()
    assert crs.sub_crs_list[0].to_epsg() == epsg
    points, line, stated, known = _truth_on_map(example, pyproj.CRS.from_epsg(epsg), step)
    exported = np.column_stack([las.x, las.y, las.z])
    assert len(exported) == len(points)
    along, across = sight_errors(exported[known], points[known], line[known])
    within = _within(np.abs(along) / stated[known])
    assert within[0] >= 0.68 and within[1] >= 0.95 and within[2] >= 0.99, within
    assert np.percentile(across, 99) < 0.005, np.percentile(across, [50, 99])
    # The DSM: the true points gridded by their true place, cell by cell.
    with rasterio.open(out / "example.dsm.tif") as dsm:
        read = pyproj.CRS.from_wkt(dsm.crs.to_wkt())  # GeoTIFF keys: the vertical by name
        assert read.sub_crs_list[0].equals(crs.sub_crs_list[0])
        assert read.sub_crs_list[1].name == crs.sub_crs_list[1].name
        assert dsm.tags(ns="IMAGE_STRUCTURE")["LAYOUT"] == "COG"
        elevation = dsm.read(1, masked=True).filled(np.nan)
        sigma = dsm.read(2, masked=True).filled(np.nan)
        cell, west, north = dsm.transform.a, dsm.transform.c, dsm.transform.f
    true_cells = gridded_truth(points[known], cell, west, north, elevation.shape)
    both = np.isfinite(true_cells) & np.isfinite(elevation)
    assert both.sum() > 0.85 * np.isfinite(elevation).sum()  # the rest: cells it missed
    within = _within(np.abs(elevation - true_cells)[both] / sigma[both])
    assert within[0] >= 0.68 and within[1] >= 0.95 and within[2] >= 0.99, within


@pytest.mark.slow
def test_the_laser_comparison_and_export_back_project_through_the_same_lens(
    example: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """Each target's estimated range in comparisons.csv is the median depth of its
    window along the ray the export back-projects that pixel through (the run's lens,
    read from depth.json); the fit finds the camera where it was placed."""
    source = open_depth(example)
    depth = np.load(example / "results" / "depth.npy")
    with (example / "results" / "comparisons.csv").open() as handle:
        rows = list(csv.DictReader(handle))
    assert len(rows) == 6
    for row in rows:
        u, v, half = float(row["u"]), float(row["v"]), int(row["window_px"]) // 2
        window = depth[round(v) - half:round(v) + half + 1, round(u) - half:round(u) + half + 1]
        ray = source.lens.rays(np.array([[u, v]]))[0]
        expected = range_on_ray(float(np.median(window[np.isfinite(window)])), tuple(ray))
        assert float(row["estimate_range_m"]) == pytest.approx(expected, abs=1e-6)  # 6 places
    assert source.run.lens_source == "fitted from the three views by the run"
    assert main(["export", str(example), "--out", str(tmp_path / "o"), "--format", "las",
                 "--step", "8", "--quiet"]) == 0
    looks = re.search(r"camera looks ([\d.]+) \+- [\d.]+ deg from true north, ([-+\d.]+) \+- "
                      r"[\d.]+ deg up, roll ([-+\d.]+)", capsys.readouterr().out)
    assert looks is not None
    # To the principal point the rig does not know (+-5 px: 0.02 degree).
    assert [float(x) for x in looks.groups()] == pytest.approx(
        [PLACEMENT.azimuth_deg, PLACEMENT.elevation_deg, PLACEMENT.roll_deg], abs=0.05)

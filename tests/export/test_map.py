"""What reaches a GIS: the DSM (a north-up COG on the map), heights with a datum (the
compound CRS, read back through pyproj), --crs, filled points flagged, and the metadata
file; every file read by a reader rigkit did not write (rasterio/GDAL, tifffile, laspy,
pyproj)."""

from __future__ import annotations

import json
import math
from pathlib import Path

import laspy
import numpy as np
import pyproj
import pytest
import rasterio
import tifffile

from rigkit.capture.tripod import TripodPosition
from rigkit.cli import main
from rigkit.export import MapRequest, export_path
from rigkit.export.dsm import NODATA, nice_cell
from rigkit.pipeline.estimate import FLAG_FILLED, FLAG_MATCHED
from tests.export.helpers import (
    camera_orientation,
    depth_plane,
    georeferenced_session,
    ground_depth,
    read_ply,
)

DOWN = camera_orientation(azimuth=47.3, elevation=-30.0, roll=0.0)
"""Looking down on flat ground 40 m below: 80 to 180 m away over the image."""
CORNERS = [(30, 280), (370, 20), (380, 270)]
GPS_TRIPOD = TripodPosition(46.55, 7.98, 1012.0, "gps:sim://gps", "2026-04-12T08:00:00Z",
                            geoid_separation_m=49.6, height_datum="gps")
F = 400 / 2 / math.tan(math.radians(3.0))  # rigs/synthetic.yaml's 6 degree view at 400 px


def ground_session(folder: Path, tripod: TripodPosition = GPS_TRIPOD,
                   flags: np.ndarray | None = None) -> Path:
    depth = ground_depth(DOWN, 40.0, F)
    return georeferenced_session(folder, DOWN, CORNERS, [0.0, 0.0, 0.0], depth=depth,
                                 tripod=tripod, flags=flags)


def _las_crs(path: Path) -> pyproj.CRS:
    las = laspy.read(path)
    assert las.header.global_encoding.wkt
    (vlr,) = [v for v in las.header.vlrs if isinstance(v, laspy.vlrs.known.WktCoordinateSystemVlr)]
    wkt = vlr.string
    assert wkt.startswith("COMPD_CS[") and "PROJCRS" not in wkt  # WKT1, what LAS 1.4 cites
    return las.header.parse_crs()


def test_a_dsm_of_flat_ground_is_flat_and_says_where_it_is(tmp_path: Path) -> None:
    """Ground 40 m below the tripod: every cell's elevation is the tripod's height less
    40 m (plus the Earth's curvature, under 2 mm here), its sigma the depth's vertical
    part; the file is a COG in the tripod's UTM zone with GGA's heights as its vertical
    CRS and -9999 as nodata (rasterio), its IFDs before its data and its GeoKeys naming
    EPSG:32632 (tifffile)."""
    session = ground_session(tmp_path)
    done = export_path(session, tmp_path / "out", ["dsm"])
    assert done.dsm is not None and [p.name for p in done.files] == ["geo.dsm.tif",
                                                                     "geo.export.json"]
    with rasterio.open(tmp_path / "out" / "geo.dsm.tif") as dsm:
        assert dsm.tags(ns="IMAGE_STRUCTURE")["LAYOUT"] == "COG"
        assert dsm.nodata == NODATA and dsm.count == 2 and dsm.dtypes == ("float32",) * 2
        assert dsm.descriptions == ("elevation", "sigma") and dsm.profile["tiled"]
        crs = pyproj.CRS.from_wkt(dsm.crs.to_wkt())
        assert crs.sub_crs_list[0].to_epsg() == 32632
        assert crs.sub_crs_list[1].name == "GPS receiver mean sea level height (GGA)"
        assert dsm.transform.a == done.dsm["cell"] == -dsm.transform.e  # north up
        corner = np.array([dsm.transform.c, dsm.transform.f]) / done.dsm["cell"]
        assert np.allclose(corner, np.round(corner), rtol=0, atol=1e-6)  # whole cells
        elevation, sigma = dsm.read(1, masked=True), dsm.read(2, masked=True)
        centres = [dsm.xy(r, c) for r, c in zip(*np.nonzero(~elevation.mask), strict=True)]
    assert elevation.count() > 1000 and elevation.mask.any()  # a fan on the map, not a box
    assert np.ma.max(np.abs(elevation - 972.0)) < 0.002
    # sigma: 1 % of the depth along the line of sight, of which its vertical share counts.
    east, north = np.array(centres).T
    e0, n0, _ = done.georef.origin
    horizontal = np.hypot(east - e0, north - n0)
    slant = np.hypot(horizontal, 40.0)
    expected = 0.01 * slant * (40.0 / slant)  # depth ~ range here to 0.1 %: ray_length
    assert np.allclose(sigma.compressed(), expected, rtol=0.02)
    with tifffile.TiffFile(tmp_path / "out" / "geo.dsm.tif") as tif:
        pages = list(tif.pages)
        keys = pages[0].geotiff_tags
        first_data = min(o for page in pages for o in page.dataoffsets if o)
        assert all(page.offset < first_data for page in pages)  # COG: IFDs first
        assert pages[0].is_tiled and pages[0].compression == 8  # DEFLATE
        assert int(keys["ProjectedCSTypeGeoKey"]) == 32632
        assert keys["VerticalCitationGeoKey"] == "GPS receiver mean sea level height (GGA)"
        assert pages[0].tags[42113].value == "-9999"


def test_the_dsm_cell_comes_from_the_spacing_or_is_given(tmp_path: Path,
                                                         capsys: pytest.CaptureFixture[str]
                                                         ) -> None:
    assert [nice_cell(x) for x in (0.0229, 0.05, 0.051, 0.3, 7.0, 1.0)] == [
        0.025, 0.05, 0.1, 0.5, 10.0, 1.0]
    session = ground_session(tmp_path)
    auto = export_path(session, tmp_path / "auto", ["dsm"]).dsm
    assert auto is not None and "median spacing" in auto["cell_chosen"]
    given = export_path(session, tmp_path / "given", ["dsm"], request=MapRequest(cell=2.0)).dsm
    assert given is not None and given["cell"] == 2.0 and given["cell_chosen"] == "given (--cell)"
    assert given["cells_with_points"] < auto["cells_with_points"]
    assert main(["export", str(session), "--out", str(tmp_path / "tiny"), "--format", "dsm",
                 "--cell", "0.001", "--quiet"]) == 2
    err = capsys.readouterr().err.strip()
    assert "--cell 0.001: " in err and "more than 8,000,000; give --cell" in err
    assert len(err.splitlines()) == 1


def test_the_dsm_needs_the_map(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    session = georeferenced_session(tmp_path, DOWN, CORNERS[:1], [0.0])  # one target
    assert main(["export", str(session), "--out", str(tmp_path / "out"), "--format",
                 "las,dsm"]) == 2
    err = capsys.readouterr().err.strip()
    assert "--format dsm needs the map, and geo is not on it: georeferencing needs 2 or " in err
    assert len(err.splitlines()) == 1 and not list((tmp_path / "out").glob("*"))


def _z(path: Path) -> np.ndarray:
    return np.asarray(laspy.read(path).z)


def test_heights_say_their_datum_and_round_trip_through_pyproj(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """A GPS's height: recorded (GGA's mean sea level, a vertical CRS named for it) or
    ellipsoidal (the altitude plus GGA's geoid separation; a 3D projected CRS in WKT1's
    COMPD_CS form). Each LAS's WKT1 read back by pyproj is the CRS written."""
    session = ground_session(tmp_path)
    recorded = export_path(session, tmp_path / "msl", ["las"])
    crs = _las_crs(tmp_path / "msl" / "geo.las")
    assert crs.equals(recorded.georef.crs) and crs.is_compound
    assert crs.sub_crs_list[0].to_epsg() == 32632 and crs.sub_crs_list[1].is_vertical
    assert crs.sub_crs_list[1].name == "GPS receiver mean sea level height (GGA)"
    assert np.allclose(_z(tmp_path / "msl" / "geo.las"), 972.0, atol=0.002)
    ellipsoidal = export_path(session, tmp_path / "ell", ["las"],
                              request=MapRequest(vertical="ellipsoidal"))
    crs = _las_crs(tmp_path / "ell" / "geo.las")
    assert crs.equals(ellipsoidal.georef.crs) and crs.is_projected and not crs.is_compound
    assert [a.name for a in crs.axis_info] == ["Easting", "Northing", "Ellipsoidal height"]
    assert np.allclose(_z(tmp_path / "ell" / "geo.las"), 972.0 + 49.6, atol=0.002)
    # The same places on the map either way (to the local frame's origin height's effect).
    for axis in ("x", "y"):
        a, b = (np.asarray(getattr(laspy.read(tmp_path / d / "geo.las"), axis))
                for d in ("msl", "ell"))
        assert np.abs(a - b).max() < 0.003
    meta = json.loads((tmp_path / "ell" / "geo.export.json").read_text())
    assert meta["place"]["crs"]["heights"].startswith("ellipsoidal height")
    assert pyproj.CRS.from_wkt(meta["place"]["crs"]["wkt1"]).equals(crs)
    # A typed height without a datum has no ellipsoidal height to give.
    typed = TripodPosition(46.55, 7.98, 1012.0, "manual", "2026-04-12T08:00:00Z")
    (tmp_path / "typed").mkdir()
    plain = ground_session(tmp_path / "typed", tripod=typed)
    assert main(["export", str(plain), "--out", str(tmp_path / "x"), "--vertical",
                 "ellipsoidal"]) == 2
    err = capsys.readouterr().err.strip()
    assert "it was typed without saying what it is measured from" in err
    export_path(plain, tmp_path / "as-typed", ["las"])
    assert _las_crs(tmp_path / "as-typed" / "geo.las").sub_crs_list[1].name == (
        "height as typed (datum not stated)")


@pytest.fixture
def egm96_grid(tmp_path_factory: pytest.TempPathFactory):  # noqa: ANN201
    """A geoid grid under EGM96's name, the geoid 47.3 m above the ellipsoid everywhere
    (a GTX file, the format PROJ's older grid names use), in PROJ's data path while the
    test runs."""
    folder = tmp_path_factory.mktemp("proj")
    rows, cols = 19, 37  # 10 degree steps over the globe
    header = np.array([-90.0, -180.0, 10.0, 10.0], ">f8").tobytes()
    header += np.array([rows, cols], ">i4").tobytes()
    (folder / "egm96_15.gtx").write_bytes(header + np.full(rows * cols, 47.3, ">f4").tobytes())
    before = pyproj.datadir.get_data_dir()
    pyproj.datadir.append_data_dir(str(folder))
    yield folder
    pyproj.datadir.set_data_dir(before)


def test_a_vertical_crs_proj_can_reach_and_one_it_cannot(
    tmp_path: Path, egm96_grid: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """--vertical EPSG:5773 (EGM96 height) through PROJ's geoid grid: the GPS's
    ellipsoidal height less the grid's 47.3 m; --vertical EPSG:3855 (EGM2008), whose
    grid PROJ lacks here: refused, naming the grid."""
    session = ground_session(tmp_path)
    done = export_path(session, tmp_path / "egm96", ["las"],
                       request=MapRequest(vertical="EPSG:5773"))
    crs = _las_crs(tmp_path / "egm96" / "geo.las")
    assert crs.sub_crs_list[1].to_epsg() == 5773 and crs.equals(done.georef.crs)
    assert np.allclose(_z(tmp_path / "egm96" / "geo.las"), 972.0 + 49.6 - 47.3, atol=0.002)
    assert "EGM96" in done.georef.map.operation
    assert main(["export", str(session), "--out", str(tmp_path / "egm08"), "--vertical",
                 "EPSG:3855"]) == 2
    err = capsys.readouterr().err.strip()
    assert "PROJ needs the grid us_nga_egm08_25.tif" in err and len(err.splitlines()) == 1
    assert main(["export", str(session), "--out", str(tmp_path / "bad"), "--vertical",
                 "EPSG:2056"]) == 2
    assert "--vertical EPSG:2056 (CH1903+ / LV95): not a vertical CRS" in (
        capsys.readouterr().err)


def test_a_national_grid_with_the_transformations_accuracy(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """--crs EPSG:2056 (Swiss LV95): the tripod where PROJ puts it on its own, the
    transformation's accuracy (1 m, WGS 84 to CH1903+) printed and kept; refusals for
    what is no projected CRS."""
    session = ground_session(tmp_path)
    assert main(["export", str(session), "--out", str(tmp_path / "lv95"), "--format", "las",
                 "--crs", "EPSG:2056", "--quiet"]) == 0
    printed = capsys.readouterr().out
    assert "frame EPSG:2056 (CH1903+ / LV95) + GPS receiver mean sea level height" in printed
    assert "Inverse of CH1903+ to WGS 84 (1) + Swiss Oblique Mercator 1995 (accuracy 1 m)" in (
        printed)
    crs = _las_crs(tmp_path / "lv95" / "geo.las")
    assert crs.sub_crs_list[0].to_epsg() == 2056
    meta = json.loads((tmp_path / "lv95" / "geo.export.json").read_text())
    assert meta["place"]["transformation"]["accuracy_m"] == 1.0
    east, north, _ = meta["place"]["tripod"]["on_map"]
    expected = pyproj.Transformer.from_crs(4979, 2056, always_xy=True).transform(
        7.98, 46.55, 1012.0 + 49.6)
    assert (east, north) == pytest.approx(expected[:2], abs=0.005)
    for crs_text, message in (
            ("EPSG:4326", "is not a projected CRS"),
            ("EPSG:2056+5728", "has heights in it: give its horizontal part to --crs"),
            ("EPSG:0", "PROJ knows no such CRS")):
        assert main(["export", str(session), "--out", str(tmp_path / "x"), "--crs",
                     crs_text]) == 2
        err = capsys.readouterr().err.strip()
        assert message in err and len(err.splitlines()) == 1


def test_filled_points_are_flagged_and_counted(tmp_path: Path) -> None:
    """flags.npy's filled bit: the LAS synthetic bit, the PLY's filled property, the
    count in the metadata; results without flags.npy say that it is not known."""
    depth = depth_plane()
    flags = np.where(np.isfinite(depth), FLAG_MATCHED, 0).astype(np.uint8)
    flags[100:140, 50:90] = FLAG_FILLED
    session = georeferenced_session(tmp_path, DOWN, CORNERS, [0.0] * 3, flags=flags,
                                    depth=depth)
    done = export_path(session, tmp_path / "out", ["ply", "las"], frame="camera")
    expected = (flags[np.isfinite(depth)] & FLAG_FILLED) != 0
    assert done.filled == 40 * 40 == expected.sum()
    assert np.array_equal(np.asarray(laspy.read(tmp_path / "out" / "geo.las").synthetic),
                          expected)
    assert np.array_equal(read_ply(tmp_path / "out" / "geo.ply")["filled"], expected)
    meta = json.loads((tmp_path / "out" / "geo.export.json").read_text())
    assert meta["points"]["filled"] == 1600
    # Counted the same with --step and without a cloud.
    only = export_path(session, tmp_path / "tif", ["tif"], step=3)
    stepped = (flags[::3, ::3] & FLAG_FILLED) != 0
    assert only.filled == int((stepped & np.isfinite(depth[::3, ::3])).sum())
    (session / "results" / "flags.npy").unlink()
    old = export_path(session, tmp_path / "old", ["ply", "las"], frame="camera")
    assert old.filled is None
    assert not np.asarray(laspy.read(tmp_path / "old" / "geo.las").synthetic).any()
    assert "filled" not in (read_ply(tmp_path / "old" / "geo.ply").dtype.names or ())
    meta = json.loads((tmp_path / "old" / "geo.export.json").read_text())
    assert meta["points"]["filled"] is None and "not known" in meta["points"]["filled_note"]


def test_the_metadata_file_holds_the_fit_and_the_budget(tmp_path: Path) -> None:
    session = ground_session(tmp_path)
    done = export_path(session, tmp_path / "out", ["las"])
    meta = json.loads((tmp_path / "out" / "geo.export.json").read_text())
    assert meta["files"] == ["geo.las"] and meta["points"]["count"] == done.points
    fit = meta["orientation"]
    assert np.allclose(fit["rotation_camera_to_enu"], DOWN, atol=1e-9)
    assert [t["name"] for t in fit["targets"]] == ["T1", "T2", "T3"]
    assert max(t["residual_deg"] for t in fit["targets"]) < 1e-6
    covariance = np.array(fit["covariance_rad2_enu"])
    assert np.allclose(covariance, covariance.T) and np.all(np.linalg.eigvalsh(covariance) > 0)
    assert fit["pointing_deg"]["elevation"] == pytest.approx(-30.0)
    budget = meta["error_budget"]
    assert budget["orientation_m"]["corner"] > budget["orientation_m"]["centre"] > 0
    assert budget["transformation_m"]["value"] == 0.0  # WGS 84 / UTM: a conversion, exact
    assert meta["place"]["tripod"]["geoid_separation_m"] == 49.6
    # The helper's run fitted the lens (the synthetic profile's pipeline does) and kept none.
    assert meta["run"]["lens"]["source"] == "fitted from the three views by the run, without " \
        "distortion"


def test_a_crs_for_elsewhere() -> None:
    """A tripod in Bavaria: LV95 has no transformation PROJ will run there (refused,
    saying the tripod lies outside its area of use); a neighbouring UTM zone does, with a
    note."""
    from rigkit.errors import InputError
    from rigkit.export.crs import map_crs

    munich = TripodPosition(48.14, 11.58, 520.0, "manual", "2026-04-12T08:00:00Z")
    with pytest.raises(InputError, match=r"outside CH1903\+ / LV95's area of use "
                                         r"\(Liechtenstein; Switzerland\); choose another"):
        map_crs(munich, "EPSG:2056")
    beside = map_crs(munich, "EPSG:32633")
    assert beside.accuracy_m == 0.0 and len(beside.notes) == 1
    assert beside.notes[0].startswith("the tripod lies outside WGS 84 / UTM zone 33N's area")
    assert map_crs(munich).horizontal_code == "EPSG:32632" and not map_crs(munich).notes

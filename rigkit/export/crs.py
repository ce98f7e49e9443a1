"""The map an export is written in: a projected CRS for easting and northing (the tripod's
UTM zone, or any projected CRS PROJ knows, ``--crs EPSG:2056``), what its heights are
measured from (``--vertical``), the CRS the files carry (horizontal plus vertical), and
PROJ's transformation from WGS 84 to it, with the accuracy PROJ states for it.

Heights. Georeferencing places a point at its height above the tripod (east, north, up
at the tripod, :mod:`rigkit.export.georef`) on top of the tripod's height. What that sum
is measured from is what the tripod's height is measured from
(:data:`rigkit.capture.tripod.HEIGHT_DATUMS`), and the file says so in its vertical CRS:

- ``recorded`` (the default): Z as the tripod's height was recorded: a GPS's height
  above its receiver's mean sea level (GGA; the receiver's geoid model, which GGA does
  not name, so the vertical CRS is named for it and carries no EPSG code; its geoid
  separation, kept with the position, is in the metadata); a height typed with an EPSG
  vertical CRS, in that CRS; a typed height without a datum, in a vertical CRS named
  "as typed, datum not stated";
- ``ellipsoidal``: heights above the output CRS's ellipsoid (for WGS 84 / UTM, WGS 84's),
  from the tripod's ellipsoidal height (a GPS's height plus its geoid separation, or one
  typed as ellipsoidal); written as a 3D projected CRS (LAS: WKT1's ``COMPD_CS`` with
  an ellipsoidal ``VERT_DATUM``, type 2002, which PROJ reads back as one);
- ``EPSG:<code>``: a vertical CRS PROJ can transform WGS 84 ellipsoidal heights to, point
  by point (a geoid model's grid: refused, naming the grid, where PROJ does not have it).

Taking the tripod's height as given for the local frame's origin, whatever it is measured
from, moves the points sideways by (the height's difference from the ellipsoidal one) x
(their distance) / (the Earth's radius): under 1 cm at 500 m for the 50 m of a geoid;
the heights' differences from the tripod are geometric (along the ellipsoid's normal),
and the geoid's slope over a scene (a few cm per km in mountains) is left out.
"""

from __future__ import annotations

import math
import warnings
from dataclasses import dataclass
from typing import Any

from rigkit.capture.tripod import (
    HEIGHT_ELLIPSOIDAL,
    HEIGHT_GPS,
    HEIGHT_UNKNOWN,
    TripodPosition,
)
from rigkit.errors import InputError
from rigkit.export.defaults import VERTICAL_ELLIPSOIDAL, VERTICAL_RECORDED

WGS84_3D = "EPSG:4979"
"""WGS 84 longitude, latitude (degrees) and ellipsoidal height (m): what georeferencing
hands to PROJ."""


@dataclass(frozen=True)
class MapCrs:
    """The map of an export. ``horizontal``: the projected CRS (pyproj); ``crs``: the one
    the files carry (compound, or projected 3D for ellipsoidal heights); ``heights``:
    what Z is, in words; ``tripod_height_m``: the tripod's height the local frame starts
    from (m, as ``heights`` says unless ``z_from_transform``, when it is ellipsoidal);
    ``z_from_transform``: Z is PROJ's (the output's ellipsoidal or vertical CRS's), else
    the tripod's height plus the height above it; ``transformer``: PROJ's
    ``WGS84_3D`` (lon, lat, h) -> (easting, northing, Z); ``operation`` its name,
    ``accuracy_m`` PROJ's accuracy for it (0: exact; None: PROJ does not know);
    ``notes``: what a surveyor should know (outside the CRS's area of use, a more
    accurate transformation whose grid PROJ lacks); ``geoid_separation_m``: the GPS's,
    where Z is a GPS's height."""

    horizontal: Any
    crs: Any
    heights: str
    tripod_height_m: float
    z_from_transform: bool
    transformer: Any
    operation: str
    accuracy_m: float | None
    notes: tuple[str, ...] = ()
    geoid_separation_m: float | None = None

    @property
    def name(self) -> str:
        return str(self.crs.name)

    @property
    def horizontal_code(self) -> str:
        """``EPSG:32632`` (authority and code), or the CRS's name when it has none."""
        found = self.horizontal.to_authority()
        return f"{found[0]}:{found[1]}" if found else str(self.horizontal.name)

    @property
    def unit_m(self) -> float:
        """Metres per unit of easting and northing (1 for metres, 0.3048... for US feet)."""
        return float(self.horizontal.axis_info[0].unit_conversion_factor)

    @property
    def vertical_name(self) -> str:
        """The vertical part's name (for an ellipsoidal height: the ellipsoid's)."""
        if self.crs.is_compound:
            return str(self.crs.sub_crs_list[1].name)
        return f"ellipsoidal height ({_datum_name(self.crs)})"

    def wkt1(self) -> tuple[str, str | None]:
        """The CRS as OGC 01-009 WKT (WKT1, GDAL's flavour: what LAS 1.4 cites), and None;
        or, for a CRS WKT1 cannot express, WKT2 and a note saying so."""
        from pyproj.enums import WktVersion
        from pyproj.exceptions import CRSError

        try:
            return self.crs.to_wkt(WktVersion.WKT1_GDAL), None
        except CRSError:
            return self.crs.to_wkt(), (f"{self.name} has no WKT1 form; the LAS file carries "
                                       "it as WKT2 (ISO 19162), which older readers may not "
                                       "parse")


def projected_crs(text: str) -> Any:
    """``--crs``'s projected CRS (``EPSG:2056``, or anything else PROJ parses); InputError
    for a CRS PROJ does not know, or one that is not a plain projected CRS."""
    import pyproj
    from pyproj.exceptions import CRSError

    try:
        crs = pyproj.CRS.from_user_input(text.strip())
    except CRSError:
        raise InputError(f"--crs {text}: PROJ knows no such CRS (give EPSG:<code> of a "
                         "projected CRS, e.g. EPSG:2056 for Swiss LV95)") from None
    if crs.is_compound:
        raise InputError(f"--crs {text} ({crs.name}) has heights in it: give its horizontal "
                         "part to --crs and the heights to --vertical")
    if not crs.is_projected or len(crs.axis_info) != 2:
        raise InputError(f"--crs {text} ({crs.name}) is not a projected CRS with easting and "
                         "northing: a map needs one (e.g. EPSG:2056, a UTM zone's EPSG:326zz)")
    return crs


def vertical_crs(text: str, what: str) -> Any:
    """The vertical CRS ``EPSG:<code>`` names; InputError (``what`` names the option)
    when PROJ does not know it as one."""
    import pyproj
    from pyproj.exceptions import CRSError

    try:
        crs = pyproj.CRS.from_user_input(text.strip())
    except CRSError:
        crs = None
    if crs is None or not crs.is_vertical or crs.is_compound:
        known = "" if crs is None else f" ({crs.name})"
        raise InputError(f"{what} {text}{known}: not a vertical CRS PROJ knows (e.g. "
                         "EPSG:5728 LN02 height, EPSG:3855 EGM2008 height)")
    return crs


def utm_epsg(lat_deg: float, lon_deg: float) -> int:
    """EPSG code of the WGS 84 UTM zone holding (lat, lon): 326zz north, 327zz south
    (the zone by longitude alone, without Norway's and Svalbard's exceptions, which is as
    exact a projection there); InputError outside UTM's 80 S to 84 N."""
    if not -80.0 <= lat_deg <= 84.0:
        raise InputError(f"latitude {lat_deg:.7g}: UTM covers 80 S to 84 N only")
    zone = min(int((lon_deg + 180.0) // 6.0) + 1, 60)
    return (32600 if lat_deg >= 0 else 32700) + zone


def map_crs(position: TripodPosition, crs: str | None = None,
            vertical: str = VERTICAL_RECORDED) -> MapCrs:
    """The map for a tripod at ``position``: ``crs`` (None: its UTM zone) and
    ``vertical`` (``recorded``, ``ellipsoidal`` or ``EPSG:<code>``); InputError naming
    what cannot be done (a height whose ellipsoidal value is not known, a grid PROJ
    lacks, a transformation PROJ does not have)."""
    import pyproj

    horizontal = (pyproj.CRS.from_epsg(utm_epsg(position.lat_deg, position.lon_deg))
                  if crs is None else projected_crs(crs))
    choice = vertical.strip()
    recorded = position.height_datum
    if choice.lower() == VERTICAL_RECORDED and recorded == HEIGHT_ELLIPSOIDAL:
        choice = VERTICAL_ELLIPSOIDAL
    if choice.lower() == VERTICAL_RECORDED:
        return _as_recorded(position, horizontal)
    if choice.lower() == VERTICAL_ELLIPSOIDAL:
        target = _ellipsoidal_3d(horizontal)
        heights = f"ellipsoidal height, m above the ellipsoid of {_datum_name(horizontal)}"
    else:
        wanted = vertical_crs(choice, "--vertical")
        if recorded.upper() == choice.upper():  # typed in that very CRS
            return _as_recorded(position, horizontal)
        target = pyproj.crs.CompoundCRS(f"{horizontal.name} + {wanted.name}",
                                        [horizontal, wanted])
        heights = f"{wanted.name} ({choice.upper()})"
    transformer, notes = _transformer(target, position)
    return MapCrs(horizontal, target, heights, _ellipsoidal_height(position), True,
                  transformer, transformer.description, _accuracy(transformer),
                  notes + _area_notes(horizontal, position))


def _as_recorded(position: TripodPosition, horizontal: Any) -> MapCrs:
    """Z as the tripod's height was recorded: the files' vertical CRS says what it is."""
    import pyproj

    datum = position.height_datum
    if datum.upper().startswith("EPSG:"):
        vertical = vertical_crs(datum, "the tripod's height datum")
        heights = f"{vertical.name} ({datum.upper()}), as the tripod's height was typed"
    else:
        name, words = {
            HEIGHT_GPS: ("GPS receiver mean sea level height (GGA)",
                         "height above mean sea level as the GPS receiver's geoid model "
                         "gives it (GGA's altitude; GGA does not name the model)"),
            HEIGHT_UNKNOWN: ("height as typed (datum not stated)",
                             "the tripod's height as typed in, datum not stated"),
        }[datum]
        vertical = pyproj.CRS.from_json_dict({
            "type": "VerticalCRS", "name": name,
            "datum": {"type": "VerticalReferenceFrame", "name": name},
            "coordinate_system": {"subtype": "vertical", "axis": [{
                "name": "Gravity-related height", "abbreviation": "H",
                "direction": "up", "unit": "metre"}]},
        })
        heights = f"{words}, plus the height above the tripod"
    target = pyproj.crs.CompoundCRS(f"{horizontal.name} + {vertical.name}",
                                    [horizontal, vertical])
    transformer, notes = _transformer(horizontal.to_3d(), position)
    separation = position.geoid_separation_m if datum == HEIGHT_GPS else None
    return MapCrs(horizontal, target, heights, position.height_m, False, transformer,
                  transformer.description, _accuracy(transformer),
                  notes + _area_notes(horizontal, position), separation)


def _ellipsoidal_3d(horizontal: Any) -> Any:
    """``horizontal`` with ellipsoidal heights as a third axis, built from WKT1 so that
    it has a WKT1 form (a COMPD_CS whose VERT_DATUM is of type 2002, ellipsoidal, which
    PROJ reads as a projected 3D CRS)."""
    import pyproj
    from pyproj.enums import WktVersion

    datum = _datum_name(horizontal).replace('"', "'")
    return pyproj.CRS.from_wkt(
        f'COMPD_CS["{horizontal.name} + ellipsoidal height",'
        f"{horizontal.to_wkt(WktVersion.WKT1_GDAL)},"
        f'VERT_CS["ellipsoidal height",VERT_DATUM["{datum}",2002],UNIT["metre",1],'
        'AXIS["Ellipsoidal height",UP]]]')


def _datum_name(crs: Any) -> str:
    datum = crs.datum
    return "an unnamed datum" if datum is None else str(datum.name)


def _ellipsoidal_height(position: TripodPosition) -> float:
    """The tripod's height above the WGS 84 ellipsoid, m; InputError when its record
    does not say it (a typed height without a datum, a GPS without a geoid separation),
    or PROJ cannot derive it from the vertical CRS it was typed in."""
    height = position.ellipsoidal_height_m
    if height is not None:
        return height
    datum = position.height_datum
    if datum.upper().startswith("EPSG:"):
        import pyproj

        vertical = vertical_crs(datum, "the tripod's height datum")
        source = pyproj.crs.CompoundCRS("WGS 84 + " + vertical.name,
                                        [pyproj.CRS.from_epsg(4326), vertical])
        transformer = _best(source, pyproj.CRS.from_user_input(WGS84_3D),
                            f"the tripod's height ({vertical.name}) to an ellipsoidal one")
        _, _, h = transformer.transform(position.lon_deg, position.lat_deg, position.height_m)
        if math.isfinite(h):
            return float(h)
        raise InputError(f"PROJ cannot take the tripod's {vertical.name} to an ellipsoidal "
                         "height there (outside its grid?)")
    why = {HEIGHT_GPS: "the GPS sent no geoid separation with it",
           HEIGHT_UNKNOWN: "it was typed without saying what it is measured from"}[datum]
    raise InputError(f"--vertical needs the tripod's height above the ellipsoid, and {why}: "
                     "record the position with --height-datum ellipsoidal (or EPSG:<code>), "
                     "or export with --vertical recorded")


def _transformer(target: Any, position: TripodPosition) -> tuple[Any, tuple[str, ...]]:
    """PROJ's most accurate transformation it can run from :data:`WGS84_3D` to
    ``target`` at the tripod, and a note where a more accurate one needs a grid PROJ
    lacks."""
    import pyproj

    outside = _area_notes(target, position)
    group = _group(pyproj.CRS.from_user_input(WGS84_3D), target, target.name, position,
                   f": {outside[0]}" if outside else "")
    best = group.transformers[0]
    better = [op for op in group.unavailable_operations
              if op.accuracy >= 0 and (best.accuracy < 0 or op.accuracy < best.accuracy)]
    if better and better[0].grids:
        return best, (f"a more accurate transformation ({better[0].name}, "
                      f"{better[0].accuracy:g} m) needs the grid "
                      f"{better[0].grids[0].short_name}, which PROJ does not have",)
    return best, ()


def _best(source: Any, target: Any, what: str) -> Any:
    """The most accurate transformation PROJ can run from ``source`` to ``target``."""
    return _group(source, target, what, None).transformers[0]


def _group(source: Any, target: Any, what: str, position: TripodPosition | None,
           why: str = "") -> Any:
    """PROJ's transformations from ``source`` to ``target`` (at ``position``), best
    first, ballpark ones (a datum ignored) left out; InputError naming the grid PROJ
    needs when it can run none (``why``: what else to say)."""
    from pyproj.transformer import AreaOfInterest, TransformerGroup

    area = None if position is None else AreaOfInterest(
        position.lon_deg, position.lat_deg, position.lon_deg, position.lat_deg)
    with warnings.catch_warnings():  # pyproj warns of a missing grid: said below instead
        warnings.simplefilter("ignore", UserWarning)
        group = TransformerGroup(source, target, always_xy=True, allow_ballpark=False,
                                 area_of_interest=area)
    if group.transformers:
        return group
    missing = [grid for op in group.unavailable_operations for grid in op.grids
               if not grid.available]
    if missing:
        raise InputError(
            f"PROJ needs the grid {missing[0].short_name} for {what} and does not have it: "
            f"projsync --file {missing[0].short_name} (or set PROJ_NETWORK=ON), or choose "
            "another --vertical")
    raise InputError(f"PROJ knows no transformation from WGS 84 to {what} there, only a "
                     f"ballpark one, which ignores the datum{why}; choose another --crs")


def _accuracy(transformer: Any) -> float | None:
    accuracy = float(transformer.accuracy)
    return accuracy if accuracy >= 0 else None


def _area_notes(crs: Any, position: TripodPosition) -> tuple[str, ...]:
    """A note when the tripod lies outside ``crs``'s area of use."""
    area = crs.area_of_use
    if area is None:
        return ()
    lon, lat = position.lon_deg, position.lat_deg
    inside = area.south <= lat <= area.north and (
        area.west <= lon <= area.east if area.west <= area.east
        else lon >= area.west or lon <= area.east)
    if inside:
        return ()
    where = area.name.split(".")[0]
    return (f"the tripod lies outside {crs.name}'s area of use ({where})",)

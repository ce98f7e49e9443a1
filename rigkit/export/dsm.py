"""A digital surface model: the georeferenced points gridded into a north-up elevation
raster in the map's CRS, written as a Cloud-Optimized GeoTIFF (COG) with a sigma band.

Two passes over the points (:func:`rigkit.export.points.point_chunks`), so that memory
stays bounded whatever the map's size:

1. :class:`Footprint` gathers the points' extent on the map and their spacing: for each
   point, the horizontal distance to its right and lower neighbours in the image (the
   larger of the two), as a histogram in log steps of 1 %. The cell size is the median
   spacing times sqrt(2) (a lattice of points that far apart, at any angle to the grid,
   leaves no cell between them empty), rounded up to 1, 2, 2.5 or 5 times a power of ten
   (in the CRS's unit); coarser where the extent would need more than
   :data:`MAX_CELLS` cells; or given (``--cell``). The grid is aligned to whole
   multiples of the cell.
2. :class:`Gridder` sums each cell's points: a cell's elevation is their mean height.
   Its sigma is what the depth's error does to that height: a point off by d along its
   line of sight (unit vector l = (l_E, l_N, l_Z)) rises by d l_Z and shifts by d along
   (l_E, l_N), where the surface's slope (g_E, g_N) changes the height under it, so the
   cell's height is off by d |l_Z - g_E l_E - g_N l_N| (d common to the cell's points:
   neighbouring depths share most of their error, so it does not shrink with their
   number). d is the points' mean sigma times their ray's length; l runs from the
   tripod to the cell; the slope is the elevation's gradient over the neighbouring
   cells. A steep face (a wall seen from the front) thus gets a large sigma: a height
   map is ill-defined there.

The file: two float32 bands, ``elevation`` and ``sigma``, nodata :data:`NODATA`, DEFLATE
with the floating-point predictor, 512 px tiles with overviews (GDAL's COG driver, via
rasterio: the layout, IFDs first and overviews before the full resolution, and the CRS's
GeoTIFF keys, vertical CRS included, are GDAL's to get right), the pixel grid's
top-left corner at (west, north) of the grid ("area" pixels).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from rigkit.errors import InputError
from rigkit.export.points import PointChunk
from rigkit.export.tiff import gdal_env

MAX_CELLS = 8_000_000
"""The most cells a DSM may have (its sums take 20 bytes a cell while gridding)."""
NODATA = -9999.0
"""The value of a cell without points, in both bands (and in the file's nodata tag)."""
NICE_STEPS = (1.0, 2.0, 2.5, 5.0)
BAND_ROWS = 256
"""Rows of the grid whose elevation and sigma are computed at a time."""
_LOG_BINS = np.arange(-6.0, 6.0 + 1e-9, 0.005)
"""Histogram edges of log10(spacing): 1.2 % steps from 1 um to 1000 km."""


def nice_cell(spacing: float) -> float:
    """The smallest of 1, 2, 2.5, 5 x 10^k that is at least ``spacing`` (> 0)."""
    power = 10.0 ** math.floor(math.log10(spacing))
    for step in (*NICE_STEPS, 10.0):
        if step * power >= spacing * (1 - 1e-12):
            return step * power
    return 10.0 * power  # pragma: no cover - the loop ends at 10


@dataclass(frozen=True)
class Grid:
    """A north-up grid: ``west``, ``north`` (its top-left corner, CRS units), ``cell``
    (CRS units), ``width`` x ``height`` cells."""

    west: float
    north: float
    cell: float
    width: int
    height: int

    @property
    def cells(self) -> int:
        return self.width * self.height

    def transform(self) -> Any:
        """The affine transform of its pixel corners (rasterio's)."""
        from affine import Affine

        return Affine(self.cell, 0.0, self.west, 0.0, -self.cell, self.north)

    def index(self, east: np.ndarray, north: np.ndarray) -> np.ndarray:
        """Flat cell index (row-major) of points (n,) on the grid."""
        col = np.clip(np.floor((east - self.west) / self.cell), 0, self.width - 1)
        row = np.clip(np.floor((self.north - north) / self.cell), 0, self.height - 1)
        return row.astype(np.int64) * self.width + col.astype(np.int64)

    def centres(self) -> tuple[np.ndarray, np.ndarray]:
        """Easting (1, W) and northing (H, 1) of the cells' centres."""
        east = self.west + (np.arange(self.width) + 0.5) * self.cell
        north = self.north - (np.arange(self.height) + 0.5) * self.cell
        return east[None, :], north[:, None]


class Footprint:
    """The first pass: the points' extent and spacing on the map (see the module)."""

    def __init__(self) -> None:
        self.low = np.array([np.inf, np.inf])
        self.high = np.array([-np.inf, -np.inf])
        self._spacing = np.zeros(len(_LOG_BINS) - 1, np.int64)

    def add(self, chunk: PointChunk) -> None:
        if not len(chunk.xyz):
            return
        en = chunk.xyz[:, :2]
        self.low = np.minimum(self.low, en.min(axis=0))
        self.high = np.maximum(self.high, en.max(axis=0))
        grid = np.full((*chunk.keep.shape, 2), np.nan)
        grid[chunk.keep] = en
        right = np.full(chunk.keep.shape, np.nan)
        down = np.full(chunk.keep.shape, np.nan)
        right[:, :-1] = np.hypot(*np.moveaxis(grid[:, 1:] - grid[:, :-1], -1, 0))
        down[:-1] = np.hypot(*np.moveaxis(grid[1:] - grid[:-1], -1, 0))
        spacing = np.fmax(right, down)[chunk.keep]  # NaN only where neither neighbour is
        spacing = spacing[np.isfinite(spacing) & (spacing > 0)]
        self._spacing += np.histogram(np.log10(spacing), _LOG_BINS)[0]

    def spacing(self) -> float:
        """The points' median spacing (CRS units; the histogram bin's upper edge)."""
        total = int(self._spacing.sum())
        if total == 0:
            raise InputError("the DSM needs points with neighbours: every estimated pixel "
                             "stands alone (export with a smaller --step)")
        index = int(np.searchsorted(np.cumsum(self._spacing), (total + 1) // 2))
        return float(10.0 ** _LOG_BINS[index + 1])

    def grid(self, cell: float | None) -> tuple[Grid, str]:
        """The grid for ``cell`` (None: chosen from the spacing) and how it was chosen;
        InputError when a given cell needs more than :data:`MAX_CELLS` cells."""
        if not np.all(np.isfinite(self.low)):
            raise InputError("the DSM has no points to grid")
        if cell is not None:
            grid = self._aligned(cell)
            if grid.cells > MAX_CELLS:
                coarsest = self._fitting(cell)
                raise InputError(
                    f"--cell {cell:g}: {grid.width} x {grid.height} cells over the points' "
                    f"extent, more than {MAX_CELLS:,}; give --cell {coarsest.cell:g} or more")
            return grid, "given (--cell)"
        spacing = self.spacing()
        wanted = nice_cell(spacing * math.sqrt(2))
        grid = self._fitting(wanted)
        how = f"the points' median spacing, {spacing:.3g}, times sqrt(2), rounded up"
        if grid.cell > wanted:
            how += f", then coarsened to stay within {MAX_CELLS:,} cells"
        return grid, how

    def _fitting(self, cell: float) -> Grid:
        """The grid of the smallest nice cell >= ``cell`` with at most MAX_CELLS cells."""
        grid = self._aligned(cell)
        while grid.cells > MAX_CELLS:
            cell = nice_cell(cell * 1.0001)
            grid = self._aligned(cell)
        return grid

    def _aligned(self, cell: float) -> Grid:
        # Whole multiples of the cell, to the nanometre: 422242.3, not 422242.30000000005.
        west = round(math.floor(self.low[0] / cell) * cell, 9)
        north = round(math.ceil(self.high[1] / cell) * cell, 9)
        width = int(math.floor((self.high[0] - west) / cell)) + 1
        height = int(math.floor((north - self.low[1]) / cell)) + 1
        return Grid(west, north, cell, width, height)


class Gridder:
    """The second pass: each cell's points summed (see the module). ``origin``: the
    tripod on the map (easting, northing, height); ``unit_m``: metres per CRS unit of
    easting and northing; ``z_unit_m``: metres per unit of height."""

    def __init__(self, grid: Grid, origin: tuple[float, float, float], unit_m: float,
                 z_unit_m: float = 1.0) -> None:
        self.grid = grid
        self._origin = origin
        self._units = (unit_m, z_unit_m)
        self._count = np.zeros(grid.cells, np.int32)
        self._height = np.zeros(grid.cells, np.float64)
        self._square = np.zeros(grid.cells, np.float64)
        self._sigma = np.zeros(grid.cells, np.float64)

    def add(self, chunk: PointChunk) -> None:
        if not len(chunk.xyz):
            return
        index = self.grid.index(chunk.xyz[:, 0], chunk.xyz[:, 1])
        low, high = int(index.min()), int(index.max())
        local = index - low
        span = slice(low, high + 1)
        size = high - low + 1
        self._count[span] += np.bincount(local, minlength=size).astype(np.int32)
        height = chunk.xyz[:, 2] - self._origin[2]  # from the tripod: squares keep digits
        self._height[span] += np.bincount(local, height, minlength=size)
        self._square[span] += np.bincount(local, height * height, minlength=size)
        reach = chunk.sigma.astype(np.float64) * chunk.ray_length
        self._sigma[span] += np.bincount(local, reach, minlength=size)

    def rasters(self) -> tuple[np.ndarray, np.ndarray]:
        """(elevation, sigma), each (H, W) float32, NaN where no point fell; computed in
        bands of :data:`BAND_ROWS` rows (with a row of their neighbours above and below
        for the slopes), so that the temporaries stay small whatever the grid's size."""
        height, width = self.grid.height, self.grid.width
        elevation = np.empty((height, width), np.float32)
        sigma = np.empty((height, width), np.float32)
        for top in range(0, height, BAND_ROWS):
            bottom = min(top + BAND_ROWS, height)
            low, high = max(top - 1, 0), min(bottom + 1, height)
            cells = slice(low * width, high * width)
            count, total, square, reach = (values[cells].reshape(high - low, width) for values
                                           in (self._count, self._height, self._square,
                                               self._sigma))
            with np.errstate(invalid="ignore", divide="ignore"):
                mean = np.where(count > 0, total / count, np.nan)
                spread = np.maximum(square / count - mean**2, 0.0)
                along = reach / count * self._height_factor(mean, low)
            band = slice(top - low, bottom - low)
            elevation[top:bottom] = (mean + self._origin[2])[band]
            sigma[top:bottom] = np.sqrt(along**2 + spread)[band]
        return elevation, sigma

    def _height_factor(self, rise: np.ndarray, first_row: int) -> np.ndarray:
        """|l_Z - g_E l_E - g_N l_N| per cell of the grid's rows from ``first_row`` on
        (``rise``: their heights above the tripod), unitless (see the module), the
        largest over the one-sided slopes to the neighbouring cells: at an edge (a wall's
        foot, a roof's rim) the two sides' slopes differ and the surface under a shifted
        point may be either."""
        unit_m, z_unit_m = self._units
        east, north = self.grid.centres()
        north = north[first_row:first_row + len(rise)]
        e0, n0, _ = self._origin
        line = np.stack(np.broadcast_arrays((east - e0) * unit_m, (north - n0) * unit_m,
                                            rise * z_unit_m))
        line /= np.linalg.norm(line, axis=0)
        scale = z_unit_m / (self.grid.cell * unit_m)
        factor = np.zeros(rise.shape)
        for slope_east in _slopes(rise, axis=1):
            for slope_north in _slopes(rise, axis=0):  # rows run south: north is -rows
                factor = np.fmax(factor, np.abs(line[2] - slope_east * scale * line[0]
                                                + slope_north * scale * line[1]))
        return factor


def _slopes(values: np.ndarray, axis: int) -> tuple[np.ndarray, np.ndarray]:
    """Per cell, the change of ``values`` per cell along ``axis`` to the next cell and
    from the one before, each the other where one is missing, 0 where both are."""
    moved = np.moveaxis(values, axis, 0)
    ahead = np.full(moved.shape, np.nan)
    behind = np.full(moved.shape, np.nan)
    ahead[:-1] = moved[1:] - moved[:-1]
    behind[1:] = moved[1:] - moved[:-1]
    ahead, behind = np.where(np.isfinite(ahead), ahead, behind), np.where(
        np.isfinite(behind), behind, ahead)
    return (np.moveaxis(np.nan_to_num(ahead, nan=0.0), 0, axis),
            np.moveaxis(np.nan_to_num(behind, nan=0.0), 0, axis))


def write_dsm(path: Path, elevation: np.ndarray, sigma: np.ndarray, grid: Grid, crs: Any,
              tags: dict[str, str]) -> None:
    """Write the two bands ((H, W) float32, NaN = no data) as a COG at ``path`` in
    ``crs`` (pyproj), with ``tags`` in its GDAL metadata."""
    import rasterio
    import rasterio.shutil
    from rasterio.io import MemoryFile

    data = np.stack([elevation, sigma])
    data[~np.isfinite(data)] = NODATA
    profile = {"driver": "GTiff", "width": grid.width, "height": grid.height, "count": 2,
               "dtype": "float32", "nodata": NODATA, "transform": grid.transform(),
               "crs": rasterio.crs.CRS.from_wkt(crs.to_wkt())}
    with gdal_env(), MemoryFile() as memory:
        with memory.open(**profile) as staged:
            staged.write(data)
            staged.descriptions = ("elevation", "sigma")
            staged.update_tags(**tags)
        with memory.open() as staged:
            rasterio.shutil.copy(staged, path, driver="COG", compress="DEFLATE",
                                 predictor="YES", blocksize=512,
                                 overview_resampling="AVERAGE", bigtiff="IF_SAFER")

"""Lens distortion from the lensfun database (through lensfunpy), in the pipeline's model.

lensfun profiles (ptlens, poly3, poly5 models, normalised in Hugin's convention, with
crop-factor and aspect corrections) are not OpenCV's radial model about the centre with
the focal length as unit. Rather than re-deriving lensfun's normalisation, this asks
lensfun itself for the distorted position of points from the centre to the corner (its
``Modifier``, exactly as it corrects an image) and fits ``k1, k2, k3`` to that map.

lensfun keeps the scale of its corrected image at a reference radius, so its centre is
shrunk or grown by a few tenths of a percent to a few percent (the ``centre_scale``).
rigkit keeps the focal length you give as the focal length at the image centre (the
paraxial one, what a lens specification states) and takes only the shape of the
profile: the corner moves by the profile's amount relative to the centre.
"""

from __future__ import annotations

import difflib
from dataclasses import dataclass

import numpy as np

from rigkit.errors import InputError
from rigkit.geometry import Distortion


@dataclass(frozen=True)
class LensfunProfile:
    """A lensfun profile converted: ``distortion`` OpenCV ``k1, k2, p1, p2, k3``
    (normalised coordinates about the image centre, focal length ``focal_px``);
    ``centre_scale`` lensfun's radial scale at the centre (dropped, see the module);
    ``fit_error_px`` the largest radial difference (radii 0 to the corner) between
    lensfun's map and the converted model; ``camera``/``lens`` as lensfun names them;
    ``focal_mm`` the real focal length the profile was interpolated at."""

    distortion: Distortion
    centre_scale: float
    fit_error_px: float
    camera: str
    lens: str
    focal_mm: float


def _lensfunpy():
    try:
        import lensfunpy  # noqa: PLC0415 - a compiled extension with its database: load on use
    except ImportError as exc:  # pragma: no cover - installed with rigkit
        raise InputError(f"lensfun profiles need lensfunpy ({exc})") from None
    return lensfunpy


def _name(item) -> str:
    return f"{item.maker} {item.model}"


def _find_camera(db, query: str):
    """The one camera whose maker and model contain every word of ``query``."""
    words = query.lower().split()
    found = [c for c in db.cameras if all(w in _name(c).lower() for w in words)]
    exact = [c for c in found if c.model.lower() == query.lower()]
    if len(found) == 1 or len(exact) == 1:
        return (exact or found)[0]
    if not found:
        names = [_name(c) for c in db.cameras]
        close = difflib.get_close_matches(query, names, n=3, cutoff=0.4)
        hint = f"; did you mean {' or '.join(repr(c) for c in close)}?" if close else ""
        raise InputError(f"lensfun has no camera {query!r}{hint}")
    listed = ", ".join(repr(_name(c)) for c in found[:5])
    raise InputError(f"lensfun camera {query!r} is ambiguous: {listed}; give more of the name")


def _find_lens(db, camera, query: str | None):
    lenses = db.find_lenses(camera, loose_search=True)
    if query:
        words = query.lower().split()
        lenses = [x for x in lenses if all(w in _name(x).lower() for w in words)]
    else:
        # A compact's built-in lens shares the camera's mount.
        lenses = [x for x in lenses if camera.mount in x.mounts] or lenses
    if len(lenses) != 1:
        what = f"lens {query!r}" if query else "a built-in lens"
        listed = ", ".join(repr(_name(x)) for x in lenses[:5]) or "none"
        raise InputError(
            f"lensfun: {what} for {_name(camera)}: found {listed}; name the lens (lens:)"
        )
    return lenses[0]


def lensfun_profile(
    camera: str,
    focal_mm: float,
    size: tuple[int, int],
    focal_px: float,
    lens: str | None = None,
) -> LensfunProfile:
    """Look up ``camera`` (words of lensfun's maker and model, e.g. ``"Coolpix P1000"``)
    and ``lens`` (None: the camera's built-in lens) at the real focal length
    ``focal_mm`` and convert its distortion for ``size`` = (W, H) px images and a focal
    length of ``focal_px``. InputError names what was not found."""
    lf = _lensfunpy()
    db = lf.Database()
    cam = _find_camera(db, camera)
    found = _find_lens(db, cam, lens)
    if not found.min_focal * 0.999 <= focal_mm <= found.max_focal * 1.001:
        raise InputError(
            f"lensfun: {_name(found)} covers {found.min_focal:g}-{found.max_focal:g} mm, "
            f"not {focal_mm:g} mm (give the real focal length, not the 35 mm equivalent)"
        )
    if not found.calib_distortion:
        raise InputError(f"lensfun has no distortion calibration for {_name(found)}")
    w, h = size
    mod = lf.Modifier(found, cam.crop_factor, w, h)
    mod.initialize(focal_mm, found.min_aperture or 4.0, 1000.0)
    # lensfun's map gives, for each pixel of the corrected image, where the camera
    # recorded it; sample it along the top row and the middle row, which together
    # cover radii from 0 to the corner.
    rows = [mod.apply_geometry_distortion(0, y, w, 1) for y in (0, h // 2)]
    centre = np.array([(w - 1) / 2, (h - 1) / 2])
    ideal = np.concatenate(
        [np.stack([np.arange(w), np.full(w, y)], axis=1) for y in (0, h // 2)]
    ).astype(np.float64)
    recorded = np.concatenate([r[0] for r in rows]).astype(np.float64)
    distortion, scale, err = _fit_radial(ideal - centre, recorded - centre, focal_px)
    return LensfunProfile(distortion, scale, err, _name(cam), _name(found), focal_mm)


def _fit_radial(ideal: np.ndarray, recorded: np.ndarray, focal_px: float):
    """Fit ``recorded = ideal * s * (1 + k1 r^2 + k2 r^4 + k3 r^6)``, r = s |ideal| / f
    (both (N, 2) px about the centre), by linear least squares on the recorded radius
    (px: what the pipeline is sensitive to). ptlens has odd powers of the radius that
    this model lacks; the misfit says how much that costs.
    Returns (distortion, s, largest radial misfit px)."""
    r_i = np.linalg.norm(ideal, axis=1)
    r_d = np.linalg.norm(recorded, axis=1)
    rho2 = (r_i / r_i.max()) ** 2
    # r_d = r_i (s + a1 rho^2 + a2 rho^4 + a3 rho^6), then rescaled to OpenCV's terms.
    A = np.stack([np.ones_like(rho2), rho2, rho2**2, rho2**3], axis=1) * r_i[:, None]
    coef, *_ = np.linalg.lstsq(A, r_d, rcond=None)
    s = float(coef[0])
    misfit = float(np.max(np.abs(A @ coef - r_d)))
    rn2 = (s * r_i.max() / focal_px) ** 2  # normalised OpenCV radius^2 at rho = 1
    k1, k2, k3 = (float(coef[j] / s / rn2**j) for j in (1, 2, 3))
    return (k1, k2, 0.0, 0.0, k3), s, misfit

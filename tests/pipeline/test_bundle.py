"""The lens stage's Jacobian (:meth:`~rigkit.pipeline.bundle.Problem.jacobian`): the
reduced (variable-projection) Jacobian of the bundle's residuals, against careful
finite differences of the residuals with every track's depth solved for again, and the
centres' fit's own Jacobian (its robust rows and the prior's) against finite
differences of its residuals."""

from __future__ import annotations

import cv2
import numpy as np
import pytest

import rigkit.pipeline.bundle as bundle
import rigkit.pipeline.distortion as distortion
from rigkit.geometry import Camera, euler_to_matrix, focal_from_fov, intrinsics
from rigkit.pipeline.bundle import Centres, Problem
from rigkit.pipeline.lens import Lens

W, H = 1200, 900
F = focal_from_fov(W, 5.0)
LENS = (-0.9, 30.0, 2e-4, -3e-4, 0.0)  # radial and tangential: ~6 px at the corner


def _problem(rng: np.random.Generator, n_terms: int) -> tuple[Problem, np.ndarray]:
    """A bundle of 150 tracks 250-350 m away, seen through ``LENS`` by three cameras
    with principal points apart (0.2 px of noise), and a random point near the truth:
    the problem, its lens and views' centres off the truth, and the point."""
    cams = {}
    for name, e, c, pp in (("left", (0, 0, 0), (0, 0, 0), (6, -4)),
                           ("right", (0.6, -0.8, 2.0), (2, 0, 0), (-5, 3)),
                           ("back", (-0.5, 0.7, -3.0), (0, -0.3, -2), (4, 7))):
        K = intrinsics(F, (W - 1) / 2 + pp[0], (H - 1) / 2 + pp[1])
        cams[name] = Camera(K=K, R=euler_to_matrix(*e).T, C=np.array(c, dtype=float),
                            width=W, height=H, distortion=LENS)
    u, v = rng.uniform(50, W - 50, 150), rng.uniform(50, H - 50, 150)
    X = cams["left"].rays(u, v) * rng.uniform(250, 350, 150)[:, None]
    tracks = (np.stack([u, v], axis=1),
              *(cams[n].project(X)[0] + rng.normal(0, 0.2, (150, 2)) for n in ("right", "back")))
    lens = Lens(F, (W, H), (LENS[0] * 0.9, LENS[1], LENS[2], LENS[3], 0.0))
    centres = np.array([[5.0, -3.0], [-4.0, 4.0], [3.0, 6.0]])
    problem = Problem(lens, tracks, 2.0, 2.0, n_terms, 1 / 300, centres)
    rv = [cv2.Rodrigues(cams[n].R)[0].ravel() for n in ("right", "back")]
    p = np.concatenate([np.full(n_terms, 6e-4), [0.0], rv[0], rv[1], [0.0, -0.3]])
    p[n_terms:] += rng.normal(0, 2e-5, p.size - n_terms)  # a few px off
    return problem, p


def _careful(fun, x: np.ndarray, steps: np.ndarray, monkeypatch: pytest.MonkeyPatch) -> np.ndarray:
    """Central differences of ``fun`` at ``x``, every depth solved to 1e-12 px."""
    monkeypatch.setattr(bundle, "DEPTH_TOL_PX", 1e-12)
    monkeypatch.setattr(bundle, "MAX_DEPTH_STEPS", 40)
    cols = []
    for k, h in enumerate(steps):
        e = np.zeros(x.size)
        e[k] = h
        cols.append((fun(x + e) - fun(x - e)) / (2 * h))
    monkeypatch.undo()
    return np.stack(cols, axis=1)


@pytest.mark.parametrize("n_terms, one_camera", [(1, False), (2, True)])
def test_the_reduced_jacobian_is_the_residuals_own(
    n_terms: int, one_camera: bool, monkeypatch: pytest.MonkeyPatch
) -> None:
    problem, p = _problem(np.random.default_rng(n_terms), n_terms)
    centres = Centres.of(problem.centres.ravel(), one_camera)
    r = problem.residuals(p)
    assert 0.05 < np.sqrt(np.mean(r**2)) < 50  # off the fit: the residuals' terms count

    def fun(x: np.ndarray) -> np.ndarray:
        problem.centres = centres.at(x[p.size :])
        return problem.residuals(x[: p.size])

    x = np.r_[p, np.zeros(centres.free)]
    steps = np.r_[1e-5 * np.maximum(1.0, np.abs(p)), np.full(centres.free, 1e-2)]
    careful = _careful(fun, x, steps, monkeypatch)
    problem.centres = centres.at(np.zeros(centres.free))
    J = problem.jacobian(p, centres.basis)
    assert J.shape == (r.size, x.size)
    err = np.linalg.norm(J - careful, axis=0) / np.linalg.norm(careful, axis=0)
    assert np.all(err < 1e-4), err
    # and it leaves the depths and centres at p's
    np.testing.assert_array_equal(problem.centres, centres.given)
    np.testing.assert_allclose(problem.residuals(p), r, atol=1e-5)


def test_the_jacobian_solves_for_the_depths_of_the_point_it_is_asked_about() -> None:
    # The residuals' depths at p, but the Jacobian asked at q (a turn of 4 px away):
    # the same as where the residuals were last at q.
    problem, p = _problem(np.random.default_rng(7), 1)
    q = p + 1e-4
    problem.residuals(p)
    at_q = problem.jacobian(q)
    problem.residuals(q)
    again = problem.jacobian(q)
    assert np.all(np.linalg.norm(at_q - again, axis=0) < 1e-5 * np.linalg.norm(again, axis=0))


def test_the_centres_fit_is_given_its_residuals_own_jacobian(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    # The centres' fit wraps the residuals in a robust loss (a square root of Cauchy's)
    # and adds the prior's rows: its Jacobian takes both by the chain rule.
    problem, p = _problem(np.random.default_rng(3), 2)
    centres = Centres.of(problem.centres.ravel(), False)
    seen = {}

    def capture(fun, x0, jac, **kwargs):
        seen.update(fun=fun, x0=x0, jac=jac)
        raise StopIteration

    monkeypatch.setattr(distortion, "least_squares", capture)
    opts = {"x_scale": np.full(p.size, 1e-3), "bounds": (np.full(p.size, -np.inf),
                                                         np.full(p.size, np.inf))}
    with pytest.raises(StopIteration):
        distortion._fit_centres_once(problem, p, opts, centres, 10.0, 0.05, 1)
    monkeypatch.undo()
    fun, x0, jac = seen["fun"], seen["x0"], seen["jac"]
    x = x0 + np.r_[np.zeros(x0.size - 6), [3.0, -2.0, 1.0, 4.0, -1.0, 2.0]]
    r = fun(x)
    assert np.max(np.abs(r[:-6])) > 2 * distortion.LOSS_SCALE_PX  # far into the loss
    J = jac(x)
    # short steps: the loss bends within a px
    steps = np.r_[1e-7 * np.maximum(1.0, np.abs(x[:-6])), np.full(6, 1e-4)]
    careful = _careful(fun, x, steps, monkeypatch)
    err = np.linalg.norm(J - careful, axis=0) / np.linalg.norm(careful, axis=0)
    assert np.all(err < 1e-4), err

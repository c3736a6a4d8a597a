"""The perspective refinement: ``reconstruct(W, K, intrinsics=...)`` (small seeded sequences)."""

import warnings

import numpy as np
import pytest

import data_tools as dt
import nrsfm
from nrsfm.stages import perspective as pp


def _orthographic(W, K, A):
    """The orthographic pipeline on the normalised tracks (it may warn: not its camera)."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", nrsfm.NRSfMWarning)
        return nrsfm.reconstruct(pp.normalise(W, A).reshape(W.shape), K)


def _seq(K=2, F=30, P=30, motion="smooth", distance=3.0, noise=0.0, seed=0):
    cam = dt.PerspectiveCamera(distance=distance)
    return dt.make_synthetic(F=F, P=P, K=K, motion=motion, seed=seed, noise=noise, camera=cam)


@pytest.mark.parametrize("K, motion", [(1, "random"), (2, "smooth"), (3, "random")])
def test_exact_perspective_data_are_reconstructed_exactly(K, motion):
    s = _seq(K=K, motion=motion, distance=2.0)
    A = s.extra["intrinsics"]
    ortho = _orthographic(s.W, K, A)
    res = nrsfm.reconstruct(s.W, K, intrinsics=A)
    assert ortho.errors(s.shapes)["e3d"] > 0.02  # the orthographic model's error
    assert res.errors(s.shapes)["e3d"] < 1e-8
    p = res.perspective
    assert res.reprojection_error() == p.reprojection_after < 1e-6  # pixels
    assert p.reprojection_before > 1.0 and p.noise < 1e-12 and p.depth_ratio < 3
    np.testing.assert_allclose(np.linalg.det(res.rotations), 1.0, atol=1e-12)
    np.testing.assert_allclose(p.translations[:, 2], 1.0)
    c, prior = p.history["cost"], p.history["prior"] > 0  # without the prior, then with it
    assert c.shape == (p.n_iter + 1,) and not prior[0]
    assert np.all(np.diff(c[~prior]) < 0) and np.all(np.diff(c[prior]) <= 0)
    assert set(res.timings) >= {"factorize", "rotations", "shape", "perspective"}
    assert "perspective refinement: " in res.summary()


@pytest.mark.parametrize("motion, disagree", [("smooth", True), ("random", False)])
def test_the_continuation_runs_where_the_depth_order_starts_disagree(motion, disagree):
    s = _seq(K=2, motion=motion)  # smooth, 30 frames: starts in two depth orders stay apart
    said = []
    res = nrsfm.reconstruct(s.W, 2, intrinsics=s.extra["intrinsics"], progress=said.append)
    free = [m for m in said if m.startswith("perspective fit without prior, start")]
    apart = sum(not m.endswith("near an earlier answer") for m in free)
    assert (apart > 1) == disagree
    assert any("from the rank-1 fit" in m for m in said) == disagree
    assert res.errors(s.shapes)["e3d"] < 1e-8


def test_camera_points_project_to_the_tracks():
    s = _seq()
    res = nrsfm.reconstruct(s.W, 2, intrinsics=s.extra["intrinsics"])
    Y = res.perspective.camera_points
    uv = s.extra["intrinsics"][:2, :2] @ (Y[:, :2] / Y[:, 2:3]) + s.extra["intrinsics"][:2, 2:]
    np.testing.assert_allclose(uv.reshape(s.W.shape), s.W, atol=1e-6)


def test_noise_gives_a_prior_and_beats_the_orthographic_model():
    s = _seq(K=2, F=40, noise=0.01, seed=1)
    A = s.extra["intrinsics"]
    res = nrsfm.reconstruct(s.W, 2, intrinsics=A)
    ortho = _orthographic(s.W, 2, A)
    assert res.perspective.mu > 0 and res.perspective.reg[0] == 0  # the first one free
    assert res.errors(s.shapes)["e3d"] < 0.5 * ortho.errors(s.shapes)["e3d"]


def test_result_does_not_depend_on_the_pixel_unit():
    s = _seq(noise=0.01, seed=2)
    A = s.extra["intrinsics"]
    a = nrsfm.reconstruct(s.W, 2, intrinsics=A)
    b = nrsfm.reconstruct(s.W * 0.7 / 3, 2, intrinsics=A * [[0.7 / 3], [0.7 / 3], [1]])
    np.testing.assert_allclose(b.perspective.camera_points, a.perspective.camera_points, atol=1e-8)


def test_missing_points_are_left_out_of_the_fit():
    s = _seq(F=40, P=30, seed=3)
    W, _ = dt.drop_tracks(s.W, 0.1, seed=0)
    res = nrsfm.reconstruct(W, 2, intrinsics=s.extra["intrinsics"])
    assert res.observed is not None and res.errors(s.shapes)["e3d"] < 1e-6


def test_intrinsics_forms_and_errors():
    f, cx, cy = 800.0, 320.0, 240.0
    M = np.array([[f, 0, cx], [0, f, cy], [0, 0, 1]])
    np.testing.assert_array_equal(pp.check_intrinsics((f, cx, cy)), M)
    np.testing.assert_array_equal(pp.check_intrinsics((f, f, cx, cy)), M)
    np.testing.assert_array_equal(pp.check_intrinsics(M.tolist()), M)
    for bad, match in [
        ((1, 2), "shape"),
        ("800", "camera matrix"),
        ((0, 320, 240), "positive"),
        ((np.nan, 320, 240), "finite"),
        (M + np.eye(3)[2] * [[0], [0], [1]], "last row"),
    ]:
        with pytest.raises(ValueError, match=match):
            pp.check_intrinsics(bad)


def test_normalise_inverts_the_camera_matrix():
    A = np.array([[700.0, 3.0, 300.0], [0.0, 650.0, 200.0], [0.0, 0.0, 1.0]])
    x = np.random.default_rng(0).standard_normal((4, 2, 5))
    np.testing.assert_allclose(pp.normalise(pp._pixels(x, A).reshape(8, 5), A), x)


def test_given_rotations_and_unused_settings_are_refused():
    s = _seq()
    with pytest.raises(ValueError, match="rotations= with intrinsics="):
        nrsfm.reconstruct(s.W, 2, rotations=s.rotations, intrinsics=s.extra["intrinsics"])
    st = nrsfm.Settings(perspective=nrsfm.PerspectiveSettings(max_iter=5))
    with pytest.raises(ValueError, match="only with intrinsics"):
        nrsfm.reconstruct(s.W, 2, settings=st)
    with pytest.raises(ValueError, match="tol"):
        nrsfm.PerspectiveSettings(tol=0)


def test_without_intrinsics_nothing_changes():
    s = dt.make_synthetic(F=30, P=20, K=2, seed=4)
    res = nrsfm.reconstruct(s.W, 2)
    assert res.perspective is None and "perspective" not in res.timings


def test_depth_ratio_of_an_answer():
    R = np.repeat(np.eye(3)[None], 2, axis=0)
    B = np.zeros((1, 3, 2))
    B[0, 2] = [-0.5, 0.5]  # depths 0.5 and 1.5 around the centroid at 1
    assert pp.depth_ratio(R, np.zeros((2, 2)), np.ones((2, 1)), B) == pytest.approx(3.0)


def test_a_fit_stops_where_it_leaves_the_depth_ratio(monkeypatch):
    s = _seq()
    x = pp.normalise(s.W, s.extra["intrinsics"])
    o = _orthographic(s.W, 2, s.extra["intrinsics"])
    state = pp._start(o.rotations, o.shapes, x.mean(axis=2), 2)
    fit = pp._Fit(x, np.ones((30, 30)), np.zeros(2))
    _, hist, converged = fit.minimise(*state, nrsfm.PerspectiveSettings(), bound=1.0)
    assert len(hist["cost"]) == 2 and converged is False  # every answer's ratio is above 1
    # no fit within the bound: they are taken on without it, to the exact answer, and warn
    monkeypatch.setattr(pp, "MAX_DEPTH_RATIO", 1.0)
    with pytest.warns(nrsfm.NRSfMWarning, match="W-perspective-depth"):
        res = nrsfm.reconstruct(s.W, 2, intrinsics=s.extra["intrinsics"])
    assert res.errors(s.shapes)["e3d"] < 1e-8 and res.perspective.converged


def test_cli_run_with_a_camera(tmp_path):
    from nrsfm.cli import main

    s = _seq()
    A = s.extra["intrinsics"]
    np.savez(tmp_path / "p.npz", W=s.W, K=2, shapes=s.shapes)
    (tmp_path / "K.txt").write_text("\n".join(", ".join(map(str, row)) for row in A))
    f, (cx, cy) = str(A[0, 0]), map(str, A[:2, 2])
    for i, camera in enumerate(
        (["--intrinsics", tmp_path / "K.txt"], ["--focal", f, "--principal", cx, cy])
    ):
        out = tmp_path / f"o{i}.npz"
        assert (
            main(["run", str(tmp_path / "p.npz"), "-o", str(out), "--quiet", *map(str, camera)])
            == 0
        )
        with np.load(out) as z:
            assert float(z["e3d"]) < 1e-8
            np.testing.assert_allclose(z["intrinsics"], A)
            assert z["translations"].shape == (30, 3) and z["perspective_cost"].ndim == 1

"""Re-projection of ground-truth shapes by new camera paths, and the external loaders."""

import numpy as np
import pytest
import scipy.io
from scipy.spatial.transform import Rotation

import data_tools as dt
from data_tools import reprojection as rp
from data_tools.external import load_external, sequence_from_camera_shapes

PATHS = ("smooth30", "smooth62", "smooth145", "smooth180", "fast", "fast10", "random")


@pytest.fixture(scope="module")
def seq():
    return dt.make_synthetic(F=40, P=15, K=2, motion="smooth", seed=3)


def test_rotvec_to_matrix_matches_scipy():
    v = np.random.default_rng(0).standard_normal((20, 3))
    v[0] = 0.0
    v[1] = [1e-10, 0, 0]
    assert np.allclose(rp.rotvec_to_matrix(v), Rotation.from_rotvec(v).as_matrix(), atol=1e-14)


def test_rotation_angle_near_0_and_180():
    ang = [1e-7, 1.0, 90.0, 179.9999, 180.0]
    R = Rotation.from_rotvec(np.radians(ang)[:, None] * [0.6, 0.0, 0.8]).as_matrix()
    assert np.allclose(rp.rotation_angle(R), ang, atol=1e-9)


def test_original_path_reproduces_w(seq):
    out = dt.reproject(seq)
    assert np.allclose(out.W, seq.W, atol=1e-12)
    assert np.allclose(out.shapes, seq.shapes, atol=1e-12)
    assert np.array_equal(out.rotations, seq.rotations)


def test_original_path_reproduces_mocap(mocap_dir):
    for name in ("pickup", "dance", "face"):
        s = dt.load_mocap(name, mocap_dir)
        out = dt.reproject(s)
        scale = np.abs(s.W).max()
        assert np.abs(out.W - s.W).max() <= 1e-12 * scale, name
        assert np.abs(out.shapes - s.shapes).max() <= 1e-12 * scale, name


@pytest.mark.parametrize("path", PATHS)
def test_paths_are_rotations_and_w_is_their_projection(seq, path):
    out = dt.reproject(seq, path, seed=5)
    R = out.rotations
    assert R.shape == (seq.n_frames, 3, 3)
    assert np.allclose(R @ R.transpose(0, 2, 1), np.eye(3), atol=1e-12)
    assert np.allclose(np.linalg.det(R), 1.0, atol=1e-12)
    assert np.allclose(out.W.reshape(-1, 2, seq.n_points), out.shapes[:, :2], atol=1e-12)
    # same world shapes: R_f' X_f is the input's world frame
    back = np.einsum("fji,fjp->fip", R, out.shapes)
    assert np.allclose(back, rp.world_shapes(seq), atol=1e-12)
    assert np.allclose(out.W.mean(axis=1), 0, atol=1e-12)


@pytest.mark.parametrize("turn", [30.0, 62.0, 90.0, 145.0])
def test_smooth_path_turns_as_stated(turn):
    R = rp.smooth(turn)(200)
    assert abs(rp.path_turn(R) - turn) < 1e-6


def test_smooth_path_with_a_one_turns_62_degrees():
    # the example: rotation vector [t, 0.4 sin 3t, 0.3 cos 2t]
    assert abs(rp.path_turn(rp._smooth_rotations(357, 1.0)) - 62.13) < 0.01


def test_smooth_180_reaches_the_opposite_view():
    assert rp.path_turn(rp.smooth(180)(357)) > 179.0


def test_fast_path_steps_by_the_stated_angle():
    R = rp.fast(25)(50, seed=1)
    steps = rp.rotation_angle(np.einsum("fji,fjk->fik", R[:-1], R[1:]))
    assert np.allclose(steps, 25.0, atol=1e-9)


def test_random_path_is_uniform():
    R = rp.random()(20000, seed=2)
    assert np.abs(R.mean(axis=0)).max() < 0.02  # Haar: E[R] = 0
    ang = rp.rotation_angle(R)
    # Haar angle density (1 - cos a) / pi: P(angle < 90 deg) = 1/2 - 1/pi
    assert abs(np.mean(ang < 90) - (0.5 - 1 / np.pi)) < 0.015


@pytest.mark.parametrize("noise", [0.01, 0.05])
def test_noise_level_as_stated(noise):
    s = dt.make_synthetic(F=200, P=60, K=2, seed=1)
    clean = dt.reproject(s, "random", seed=4)
    noisy = dt.reproject(s, "random", noise=noise, seed=4)
    ref = np.mean(np.std(clean.W, axis=1))
    P = s.n_points
    # the added noise (std noise * ref) is re-centred per row: variance times (P - 1) / P
    measured = np.std(noisy.W - clean.W) / np.sqrt((P - 1) / P)
    assert abs(measured / (noise * ref) - 1) < 0.02
    assert np.array_equal(noisy.shapes, clean.shapes)


def test_deterministic_under_seed(seq):
    for path in ("fast", "random"):
        a = dt.reproject(seq, path, noise=0.02, seed=7)
        b = dt.reproject(seq, path, noise=0.02, seed=7)
        c = dt.reproject(seq, path, noise=0.02, seed=8)
        assert np.array_equal(a.W, b.W) and np.array_equal(a.rotations, b.rotations)
        assert not np.allclose(a.W, c.W)


def test_validation_set_rows_do_not_depend_on_order(seq):
    rows = [("s", "fast", 0.0), ("s", "smooth62", 0.02), ("s", "random", 0.01)]
    calls = []

    def load(name):
        calls.append(name)
        return seq

    first = dt.validation_set(rows, load, seed=1)
    second = dt.validation_set(rows[::-1], load, seed=1)[::-1]
    assert calls == ["s", "s"]  # loaded once per call
    calls.clear()
    for a, b in zip(first, second):
        assert np.array_equal(a.W, b.W)
    same_path = dt.validation_set([("s", "random", 0.0), ("s", "random", 0.05)], load, seed=1)
    assert np.array_equal(same_path[0].rotations, same_path[1].rotations)
    assert not np.allclose(same_path[0].W, same_path[1].W)
    assert [s.name for s in first] == [
        "synthetic-smooth/fast40/noise0",
        "synthetic-smooth/smooth62/noise0.02",
        "synthetic-smooth/random/noise0.01",
    ]


def test_bad_inputs(seq):
    with pytest.raises(ValueError, match="unknown camera path"):
        dt.parse_path("spiral")
    with pytest.raises(ValueError, match="needs a turn"):
        dt.parse_path("smooth")
    with pytest.raises(ValueError, match="turn must be"):
        rp.smooth(200)
    with pytest.raises(ValueError, match=r"\(F, 3, 3\) = \(40, 3, 3\)"):
        dt.reproject(seq, np.zeros((3, 3, 3)))
    with pytest.raises(ValueError, match=r"\(F, 3, P\)"):
        rp.project(np.zeros((4, 2, 5)), np.zeros((4, 3, 3)))


def _struct_array(field, arrays):
    out = np.zeros((1, len(arrays)), dtype=[(field, object)])
    for i, a in enumerate(arrays):
        out[0, i][field] = a
    return out


def test_load_external_struct_format(tmp_path):
    rng = np.random.default_rng(0)
    F, P = 6, 9
    X = rng.standard_normal((F, 3, P)) + [[[0], [0], [5]]]
    X_nan = X.copy()
    X_nan[2, 1, 4] = np.nan  # point 4 missing in frame 2: dropped everywhere
    folder = tmp_path / "hulk"
    folder.mkdir()
    scipy.io.savemat(
        folder / "data_hulk.mat",
        {
            "Pgth": _struct_array("P", list(X_nan)),
            "p": _struct_array("p", [x[:2] / x[2] for x in X]),
            "v": np.ones((F, P)),
        },
    )
    s = load_external("hulk", tmp_path)
    keep = np.arange(P) != 4
    Xc = X[:, :, keep] - X[:, :, keep].mean(axis=2, keepdims=True)
    assert s.W.shape == (2 * F, P - 1)
    assert np.allclose(s.shapes, Xc)
    assert np.allclose(s.W, Xc[:, :2].reshape(2 * F, -1))
    assert np.allclose(s.rotations, np.eye(3))
    assert s.extra["image_tracks"].shape == (F, 2, P - 1)
    assert s.K == dt.EXTERNAL["hulk"][2] and "intrinsics" not in s.extra
    (folder / "intrinsics_hulk.txt").write_text("800, 0, 320\n0, 790, 240\n0, 0, 1\n")
    A = load_external("hulk", tmp_path).extra["intrinsics"]
    np.testing.assert_array_equal(A, [[800, 0, 320], [0, 790, 240], [0, 0, 1]])


def test_load_external_tracks3d_format(tmp_path, monkeypatch):
    rng = np.random.default_rng(1)
    F, P = 7, 8
    T = rng.standard_normal((3, P, F))
    T[:, 3, 5] = 0.0  # point 3 lost in frame 5
    scipy.io.savemat(tmp_path / "back_L_3D.mat", {"track3D": T})
    monkeypatch.setenv("NRSFM_EXTERNAL_DATA", str(tmp_path))
    s = load_external("back", K=2)
    keep = np.arange(P) != 3
    X = T[:, keep].transpose(2, 0, 1)
    assert s.K == 2 and s.W.shape == (2 * F, P - 1)
    assert np.allclose(s.shapes, X - X.mean(axis=2, keepdims=True))


def test_load_external_errors(tmp_path, monkeypatch):
    monkeypatch.delenv("NRSFM_EXTERNAL_DATA", raising=False)
    monkeypatch.delenv("NRSFM_DATA", raising=False)
    with pytest.raises(FileNotFoundError, match="NRSFM_EXTERNAL_DATA or NRSFM_DATA"):
        load_external("back")
    with pytest.raises(ValueError, match="unknown external sequence"):
        load_external("nope", tmp_path)
    with pytest.raises(FileNotFoundError, match="back_L_3D.mat"):
        load_external("back", tmp_path)
    scipy.io.savemat(tmp_path / "back_L_3D.mat", {"track3D": np.ones((2, 4, 3))})
    with pytest.raises(ValueError, match=r"track3D must have shape \(3, P, F\)"):
        load_external("back", tmp_path)
    with pytest.raises(ValueError, match=r"\(F, 3, P\)"):
        sequence_from_camera_shapes("x", np.zeros((3, 2, 4)))

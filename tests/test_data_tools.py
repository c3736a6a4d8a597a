import numpy as np
import pytest

import data_tools as dt
from data_tools.mocap import AKHTER


@pytest.mark.parametrize("name", dt.MOCAP_NAMES)
def test_load_mocap_shapes_and_camera_frame(mocap_dir, name):
    seq = dt.load_mocap(name, mocap_dir)
    F, P = seq.n_frames, seq.n_points
    assert seq.W.shape == (2 * F, P)
    assert seq.shapes.shape == (F, 3, P)
    assert seq.K == dt.MOCAP_K[name]
    # rows centred, shapes centred per frame
    assert np.abs(seq.W.mean(axis=1)).max() < 1e-9 * np.abs(seq.W).max()
    assert np.abs(seq.shapes.mean(axis=2)).max() < 1e-9 * np.abs(seq.shapes).max()
    # camera-frame ground truth reproduces W by orthographic projection
    np.testing.assert_allclose(
        seq.shapes[:, :2].reshape(2 * F, P), seq.W, atol=1e-9 * np.abs(seq.W).max()
    )
    if name in AKHTER:
        R = seq.rotations
        assert R.shape == (F, 3, 3)
        np.testing.assert_allclose(
            R @ R.transpose(0, 2, 1), np.broadcast_to(np.eye(3), R.shape), atol=1e-9
        )
        np.testing.assert_allclose(np.linalg.det(R), 1.0, atol=1e-9)
        np.testing.assert_allclose(R @ seq.world_shapes, seq.shapes, atol=1e-12)
    else:
        assert seq.rotations is None


def test_sizes_match_the_paper(mocap_dir):
    sizes = {n: (s.n_frames, s.n_points) for n, s in dt.load_all(mocap_dir).items()}
    assert sizes == {
        "drink": (1102, 41),
        "pickup": (357, 41),
        "yoga": (307, 41),
        "stretch": (370, 41),
        "dance": (264, 75),
        "face": (316, 40),
        "walking": (260, 55),
        "shark": (240, 91),
    }


def test_akhter_layout_skeleton_and_scale(mocap_dir):
    seq = dt.load_mocap("pickup", mocap_dir)
    assert seq.edges.min() == 0 and seq.edges.max() < seq.n_points
    assert np.mean(np.std(seq.world_shapes, axis=2)) == pytest.approx(1.0, abs=1e-9)


def test_torresani_layout_is_stacked_by_coordinate(mocap_dir):
    import scipy.io

    raw = scipy.io.loadmat(str(mocap_dir / "walking.mat"))["P3_gt"]
    seq = dt.load_mocap("walking", mocap_dir)
    F = seq.n_frames
    f = 17
    x = raw[f] - raw[f].mean()
    z = raw[2 * F + f] - raw[2 * F + f].mean()
    np.testing.assert_allclose(seq.shapes[f, 0], x)
    np.testing.assert_allclose(seq.shapes[f, 2], z)


def test_missing_file_says_where_it_looked(tmp_path):
    with pytest.raises(FileNotFoundError, match=str(tmp_path)):
        dt.load_mocap("drink", tmp_path)
    with pytest.raises(FileNotFoundError, match="no such folder"):
        dt.load_mocap("drink", tmp_path / "nowhere")


def test_default_dir_from_env(monkeypatch, tmp_path):
    monkeypatch.delenv("NRSFM_DATA", raising=False)
    with pytest.raises(FileNotFoundError, match="NRSFM_DATA"):
        dt.load_mocap("drink")
    monkeypatch.setenv("NRSFM_DATA", str(tmp_path))
    with pytest.raises(FileNotFoundError, match=str(tmp_path / "mocap")):
        dt.load_mocap("drink")


def test_unknown_sequence():
    with pytest.raises(ValueError, match="unknown MoCap sequence"):
        dt.load_mocap("juggling")


@pytest.mark.parametrize("motion", dt.MOTIONS)
def test_synthetic_ground_truth_is_consistent(motion):
    seq = dt.make_synthetic(F=40, P=20, K=3, motion=motion, seed=3)
    F, P = 40, 20
    assert seq.W.shape == (2 * F, P) and seq.shapes.shape == (F, 3, P)
    np.testing.assert_allclose(seq.shapes[:, :2].reshape(2 * F, P), seq.W, atol=1e-12)
    np.testing.assert_allclose(seq.rotations @ seq.world_shapes, seq.shapes, atol=1e-12)
    R = seq.rotations
    np.testing.assert_allclose(np.linalg.det(R), 1.0, atol=1e-12)
    # low rank: X# has rank K, W has rank <= 3K
    s = np.linalg.svd(seq.world_shapes.reshape(F, -1), compute_uv=False)
    assert s[3] < 1e-10 * s[0] and s[2] > 1e-3 * s[0]
    assert np.linalg.matrix_rank(seq.W, tol=1e-9 * np.abs(seq.W).max()) <= 9


def test_synthetic_motion_kinds_differ():
    def step_deg(motion):
        R = dt.make_synthetic(F=30, P=12, K=2, motion=motion, seed=1).rotations
        rel = np.einsum("fij,fkj->fik", R[1:], R[:-1])
        ang = np.arccos(np.clip((np.trace(rel, axis1=1, axis2=2) - 1) / 2, -1, 1))
        return np.degrees(ang).mean()

    static, smooth, fast, rand = (step_deg(m) for m in ("static", "smooth", "fast", "random"))
    assert static < 1 < smooth < 10 < fast < rand


def test_synthetic_is_seeded_and_noise_is_applied():
    a = dt.make_synthetic(F=20, P=12, K=2, seed=5, noise=0.01)
    b = dt.make_synthetic(F=20, P=12, K=2, seed=5, noise=0.01)
    c = dt.make_synthetic(F=20, P=12, K=2, seed=6, noise=0.01)
    np.testing.assert_array_equal(a.W, b.W)
    assert not np.allclose(a.W, c.W)
    rel = np.std(a.W - a.extra["W_clean"]) / np.mean(np.std(a.extra["W_clean"], axis=1))
    assert 0.005 < rel < 0.02
    with pytest.raises(ValueError, match="too large"):
        dt.make_synthetic(F=3, P=12, K=3)


def test_perspective_camera_projects_the_same_shapes_through_its_intrinsics():
    cam = dt.PerspectiveCamera(distance=3.0, focal=600.0, principal=(300.0, 200.0))
    persp = dt.make_synthetic(F=20, P=15, K=2, seed=4, camera=cam)
    ortho = dt.make_synthetic(F=20, P=15, K=2, seed=4)
    np.testing.assert_array_equal(persp.shapes, ortho.shapes)  # the same draws
    np.testing.assert_array_equal(persp.rotations, ortho.rotations)
    depth = persp.extra["depth"]
    X = persp.shapes + np.array([0.0, 0.0, depth])[None, :, None]
    homogeneous = np.einsum("ij,fjp->fip", persp.extra["intrinsics"], X)
    pixels = homogeneous[:, :2] / homogeneous[:, 2:]
    np.testing.assert_allclose(persp.W.reshape(20, 2, 15), pixels, rtol=1e-12)
    # the distance is in object radii: the nearest point is in front, at least depth / 3 away
    radius = np.linalg.norm(persp.world_shapes, axis=1).max()
    assert depth == pytest.approx(3.0 * radius) and X[:, 2].min() >= depth - radius


def test_a_far_perspective_camera_is_nearly_orthographic():
    cam = dt.PerspectiveCamera(distance=500.0, focal=1.0, principal=(0.0, 0.0))
    persp = dt.make_synthetic(F=10, P=12, K=1, seed=1, camera=cam)
    ortho = dt.make_synthetic(F=10, P=12, K=1, seed=1)
    W = persp.W * persp.extra["depth"]  # weak perspective: pixels x depth / focal
    W = W - W.mean(axis=1, keepdims=True)
    assert np.abs(W - ortho.W).max() < 0.01 * np.abs(ortho.W).max()


@pytest.mark.parametrize(
    "kwargs, match",
    [
        (dict(distance=1.0), "distance must be above 1"),
        (dict(distance=float("nan")), "distance"),
        (dict(focal=0.0), "focal must be positive"),
        (dict(principal=(1.0,)), "principal must be two numbers"),
    ],
)
def test_perspective_camera_names_a_bad_value(kwargs, match):
    with pytest.raises(ValueError, match=match):
        dt.PerspectiveCamera(**kwargs)


def test_noise_and_missing_data_generators():
    W = dt.make_synthetic(F=30, P=15, K=2, seed=0).W
    Wn = dt.add_noise(W, 0.05, seed=1)
    np.testing.assert_allclose(Wn.mean(axis=1), 0, atol=1e-12)
    np.testing.assert_array_equal(Wn, dt.add_noise(W, 0.05, seed=1))
    Wm, mask = dt.drop_tracks(W, 0.3, seed=2)
    assert mask.shape == (30, 15)
    assert 0.2 < 1 - mask.mean() < 0.4
    assert np.isnan(Wm).sum() == 2 * (~mask).sum()
    np.testing.assert_array_equal(Wm[0::2][mask], W[0::2][mask])
    with pytest.raises(ValueError):
        dt.drop_tracks(W, 1.0)


def _runs(column):
    """Number of runs of missing frames in one (F,) observed column."""
    gaps = ~column
    return int(gaps[0]) + int(np.sum(gaps[1:] & ~gaps[:-1]))


@pytest.mark.parametrize(
    "pattern", [p for p in dt.noise.PATTERNS if p not in ("uniform", "tracking")]
)
def test_track_patterns_honour_the_fraction_their_shape_and_the_seed(pattern):
    """lost / late / block: exactly round(fraction P) tracks hit, each with one gap of the
    pattern's shape; the same seed the same mask, another seed another."""
    F, P = 50, 41
    W = np.random.default_rng(0).standard_normal((2 * F, P))
    Wm, mask = dt.drop_tracks(W, 0.3, seed=31, pattern=pattern)
    hit = ~mask.all(axis=0)
    assert hit.sum() == round(0.3 * P) == 12
    assert all(_runs(mask[:, p]) == 1 for p in np.flatnonzero(hit))
    tenth = -(-F // 10)
    if pattern == "lost":  # seen in the first tenth, lost to the end
        assert mask[:tenth].all() and not mask[-1, hit].any()
    elif pattern == "late":  # unseen at first, seen in the last tenth
        assert mask[-tenth:].all() and not mask[0, hit].any()
    else:  # gone for a block and back
        assert mask[0].all() and mask[-1].all()
        assert (~mask[:, hit]).sum(axis=0).min() >= tenth
    np.testing.assert_array_equal(np.isnan(Wm), np.repeat(~mask, 2, axis=0))
    np.testing.assert_array_equal(mask, dt.drop_tracks(W, 0.3, seed=31, pattern=pattern)[1])
    assert not np.array_equal(mask, dt.drop_tracks(W, 0.3, seed=32, pattern=pattern)[1])
    assert dt.drop_tracks(W, 0.0, seed=31, pattern=pattern)[1].all()


def test_lost_pattern_is_about_fifteen_percent_of_the_entries():
    """The lost-tracks pattern: 30% of the tracks lost after the first tenth, ~15% of the
    entries (0.3 x the mean lost share 0.45 = 0.135, plus the draw's spread)."""
    W = np.zeros((2 * 300, 41))
    _, mask = dt.drop_tracks(W, 0.3, seed=31, pattern="lost")
    assert 0.10 < 1 - mask.mean() < 0.20


def test_drop_tracks_names_bad_patterns_and_short_sequences():
    W = np.zeros((4, 10))
    with pytest.raises(ValueError, match=r"pattern must be one of \['uniform', 'tracking'"):
        dt.drop_tracks(W, 0.3, pattern="lost-tracks")
    with pytest.raises(ValueError, match="block pattern needs at least 3 frames"):
        dt.drop_tracks(W, 0.3, pattern="block")
    assert dt.drop_tracks(W, 0.3, pattern="uniform")[1].shape == (2, 10)


def test_tracks_from_frames_follows_moving_dots():
    cv2 = pytest.importorskip("cv2")
    rng = np.random.default_rng(0)
    base = rng.uniform(40, 200, (25, 2))
    frames = []
    for f in range(8):
        img = np.zeros((240, 240), np.uint8)
        for x, y in base + [2.0 * f, 1.0 * f]:
            cv2.circle(img, (int(round(x)), int(round(y))), 3, 255, -1)
        frames.append(img)
    tracks = dt.tracks_from_frames(frames)
    assert tracks.shape[0] == 8 and tracks.shape[1] == 2 and tracks.shape[2] >= 20
    np.testing.assert_allclose((tracks[-1] - tracks[0]).mean(axis=1), [14.0, 7.0], atol=0.5)
    with pytest.raises(ValueError):
        dt.tracks_from_frames([])

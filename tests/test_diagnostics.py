"""Diagnostics: input checks from the maths and the quality signals of a run."""

import warnings

import numpy as np
import pytest
from threadpoolctl import threadpool_limits

import data_tools
import nrsfm
from nrsfm import diagnostics as D
from nrsfm.settings import RotationSettings
from nrsfm.stages.measurement import factorize
from nrsfm.stages.rotations import estimate_rotations


@pytest.fixture(autouse=True)
def _one_thread():
    with threadpool_limits(limits=1):
        yield


def _planar(F=60, P=20, K=2, seed=0):
    """A deforming planar object (z = 0 in every basis shape): rank(W) = 2K < 3K."""
    seq = data_tools.make_synthetic(F=F, P=P, K=K, seed=seed)
    B = seq.extra["basis"].copy()
    B[:, 2] = 0.0
    X = np.einsum("fk,kip->fip", seq.extra["coefficients"], B)
    return (seq.rotations[:, :2] @ X).reshape(2 * F, P)


def _run(W, K, **kw):
    """reconstruct(W, K); its NRSfMWarnings. Any other warning fails (W of rank below 3K
    included: the shape stage's closed form works in W's column space, where the rank-K fit
    is unique)."""
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        res = nrsfm.reconstruct(W, K, **kw)
    flags = [w for w in caught if issubclass(w.category, nrsfm.NRSfMWarning)]
    other = [(w.category, str(w.message)[:40]) for w in caught if w not in flags]
    assert not other, other
    return res, flags


def test_three_K_above_centred_rank_is_value_error_naming_both():
    W = np.random.default_rng(0).standard_normal((20, 3))  # K = 1, P = 3: rank <= 2
    with pytest.raises(ValueError, match=r"min\(2F, P - 1\) = 2, below 3K = 3"):
        nrsfm.reconstruct(W, 1)


def test_planar_object_rank_deficient_warns_with_rank():
    res, caught = _run(
        _planar(), 2, settings=nrsfm.Settings(rotation=RotationSettings(max_starts=6))
    )
    assert len(caught) == 1
    msg = str(caught[0].message)
    assert msg.startswith(
        "unreliable reconstruction: W-rank-deficient: W has only 4 "
        "independent directions where the model with K = 2 needs 3K = 6"
    )
    assert res.diagnostics.signals["numerical_rank"] == 4
    assert res.diagnostics.flagged


def test_static_camera_warns():
    seq = data_tools.make_synthetic(F=60, P=20, K=2, motion="static", seed=0)
    res, caught = _run(seq.W, 2)
    assert len(caught) == 1 and "W-static-camera: " in str(caught[0].message)
    assert res.diagnostics.signals["camera_spread_deg"] < D.CAMERA_SPREAD_MIN_DEG


def test_transposed_input_warns():
    seq = data_tools.make_synthetic(F=60, P=30, K=2, seed=1)  # W is 120 x 30
    res, caught = _run(
        seq.W.T, 2, settings=nrsfm.Settings(rotation=RotationSettings(max_starts=8))
    )  # read as 15 x 120
    assert len(caught) == 1
    msg = str(caught[0].message)
    assert "looks transposed" in msg and "W.T" in msg
    assert res.diagnostics.signals["looks_transposed"]


@pytest.mark.parametrize("noise", [0.0, 0.03])
def test_clean_and_mildly_noisy_inputs_do_not_warn(noise):
    seq = data_tools.make_synthetic(F=60, P=30, K=2, noise=noise, seed=2)
    with warnings.catch_warnings():
        warnings.simplefilter("error", nrsfm.NRSfMWarning)
        res = nrsfm.reconstruct(seq.W, 2)
    d = res.diagnostics
    assert not d.flagged and d.signals["triplet_hits"] >= 2
    assert d.signals["triplet_cost_ratio"] < D.COST_RATIO_MAX
    for name in (
        "numerical_rank",
        "rank_gap",
        "condition",
        "triplet_cost_ratio",
        "kept_fraction",
        "smoothness_sign_fraction",
        "camera_spread_deg",
    ):
        assert name in d.signals and name in d.thresholds


def test_default_demo_sequence_does_not_warn():
    seq = data_tools.default_sequence()
    with warnings.catch_warnings():
        warnings.simplefilter("error", nrsfm.NRSfMWarning)
        res = nrsfm.reconstruct(seq.W, seq.K)
    assert res.diagnostics.flags == [] and res.diagnostics.notes == []


def test_predicted_triplet_cost_matches_noise():
    """Dai's cost at the found triplet is the size the noise model predicts (within 2x)."""
    seq = data_tools.make_synthetic(F=120, P=40, K=2, noise=0.03, seed=4)
    res = nrsfm.reconstruct(seq.W, 2, method="bmm")
    s = res.diagnostics.signals
    assert 0.5 < s["triplet_cost"] / s["triplet_cost_predicted"] < 2.0
    assert 0.5 < s["noise_level"] / 0.03 < 2.0


def test_bad_triplet_is_flagged():
    """A triplet far from the best minimum: the cost ratio flags it."""
    seq = data_tools.make_synthetic(F=80, P=30, K=2, noise=0.02, seed=5)
    f = factorize(seq.W, 2)
    good = estimate_rotations(f.M_hat, 2, single=True)
    bad = estimate_rotations(f.M_hat, 2, single=True)
    G = np.random.default_rng(0).standard_normal((6, 3))
    bad.search.costs = np.array([nrsfm.stages.corrective.triplet_cost(G, f.M_hat)])
    bad.G = G[None]
    d_good = D.diagnose(seq.W, 2, f, good)
    d_bad = D.diagnose(seq.W, 2, f, bad)
    assert d_good.signals["triplet_cost_ratio"] < D.COST_RATIO_MAX
    assert d_bad.signals["triplet_cost_ratio"] > D.COST_RATIO_MAX
    assert any(flag.startswith("W-triplet-bad-minimum: ") for flag in d_bad.flags)


def test_warning_class_and_report(tmp_path, capsys):
    assert issubclass(nrsfm.NRSfMWarning, UserWarning)
    res, _ = _run(_planar(), 2, settings=nrsfm.Settings(rotation=RotationSettings(max_starts=6)))
    text = res.diagnostics.summary()
    assert "WARNING" in text and "numerical_rank = 4" in text
    pytest.importorskip("rerun")
    from nrsfm.views import recording_content

    assert "## Diagnostics" in recording_content(res).report
    path = tmp_path / "planar.npz"
    np.savez(path, W=_planar(), K=2)
    from nrsfm.cli import main

    with warnings.catch_warnings():
        warnings.simplefilter("error", nrsfm.NRSfMWarning)  # the CLI prints, not warns
        main(["run", str(path), "-o", str(tmp_path / "out.npz"), "--quiet"])
    out, err = capsys.readouterr()
    assert err == "", err  # no other warning (the flag is in the report)
    assert "WARNING: W-rank-deficient: W has only 4 independent directions" in out


def test_depth_amplification_reads_the_cameras_against_the_modes():
    """1 for cameras from all directions, inf for a static camera, large where the
    deformation moves while the camera turns through a small angle; scale free."""
    from data_tools.reprojection import reproject, smooth
    from nrsfm.metrics import depth_amplification

    seq = data_tools.make_synthetic(F=200, P=30, K=2, motion="random", seed=1)
    amp = depth_amplification(seq.rotations, seq.shapes, 2)
    assert 0.9 < amp < 1.2
    assert depth_amplification(seq.rotations, 1e3 * seq.shapes, 2) == pytest.approx(amp)
    fixed = np.broadcast_to(np.eye(3), seq.rotations.shape)
    assert depth_amplification(fixed, seq.shapes, 2) == np.inf
    static = data_tools.make_synthetic(F=60, P=20, K=2, motion="static", seed=0)
    assert depth_amplification(static.rotations, static.shapes, 2) > 1e3
    narrow = reproject(seq, smooth(20.0), seed=0)
    assert depth_amplification(narrow.rotations, narrow.world_shapes, 2) > 10 * amp
    assert np.isnan(depth_amplification(seq.rotations, 0 * seq.shapes, 2))


def test_random_cameras_warn_that_the_depth_signs_are_not_determined():
    """A camera that really jumps between frames: the depth signs come from smoothness,
    which cannot decide them (a mirror image per frame): one warning, W-camera-jumps, while
    the shapes are right up to each frame's mirror (e3d factors it out)."""
    seq = data_tools.make_synthetic(F=80, P=30, K=2, motion="random", seed=2)
    res, caught = _run(seq.W, 2)
    assert [str(w.message) for w in caught] == [res.diagnostics.message]
    assert res.diagnostics.flags[0].startswith("W-camera-jumps: the cameras jump: ")
    assert res.diagnostics.signals["smoothness_sign_fraction"] > D.SIGN_FRACTION_MAX
    assert nrsfm.e3d(res.shapes, seq.shapes) < 1e-6
    assert nrsfm.rotation_error(res.rotations, seq.rotations) > 0.5  # mirrored frames
    smooth = data_tools.make_synthetic(F=80, P=30, K=2, seed=2)
    res, caught = _run(smooth.W, 2)
    assert caught == [] and res.diagnostics.signals["smoothness_sign_fraction"] == 0


def test_rank_deficient_w_on_random_cameras_with_an_exact_triplet_warns_only_the_jumps():
    """A rigid body plus a planar deformation (W of rank 5 < 3K = 6) seen by a camera that
    jumps: the triplet fits W exactly, so the rank is a note (as without the jumps) and the
    jumps the one warning; the deforming planar object, whose triplet does not fit, warns
    more (test above)."""
    seq = data_tools.make_rank_deficient(motion="random", seed=0)
    res, caught = _run(seq.W, 2)
    assert len(caught) == 1
    assert [f.split(":")[0] for f in res.diagnostics.flags] == ["W-camera-jumps"]
    assert any(n.startswith("N-rank-deficient") for n in res.diagnostics.notes)
    assert res.diagnostics.signals["numerical_rank"] == 5
    assert nrsfm.e3d(res.shapes, seq.shapes) < 1e-6


def test_narrow_camera_path_warns_depth_undetermined():
    """Shapes re-projected by a camera that turns 20 degrees, 1 % noise: the depth of the
    deformation is the prior's, and the run says so (given rotations too); without noise
    the rank-3K W has one exact answer and the run is silent."""
    from data_tools.reprojection import reproject, smooth

    base = data_tools.make_synthetic(F=120, P=30, K=2, seed=3)
    exact = reproject(base, smooth(20.0), seed=0)
    res, caught = _run(exact.W, 2, rotations=exact.rotations)
    assert caught == [] and nrsfm.e3d(res.shapes, exact.shapes) < 1e-6
    assert res.diagnostics.signals["depth_amplification"] > D.DEPTH_AMPLIFICATION_MAX
    seq = reproject(base, smooth(20.0), noise=0.01, seed=0)
    for kw in ({}, dict(rotations=seq.rotations)):
        res, caught = _run(seq.W, 2, **kw)
        assert res.diagnostics.signals["depth_amplification"] > D.DEPTH_AMPLIFICATION_MAX
        assert len(caught) == 1 and "W-depth-undetermined: " in str(caught[0].message)


def test_an_infinite_depth_amplification_reads_in_words():
    """The depth flag of cameras that never see a direction of a mode says so, not "inf x"."""
    seq = data_tools.make_synthetic(F=30, P=20, K=2, noise=0.02, seed=1)
    d = D.diagnose(seq.W, 2, factorize(seq.W, 2), depth_amplification=np.inf)
    (flag,) = [f for f in d.flags if f.startswith("W-depth-undetermined: ")]
    assert "no camera sees one of its directions" in flag and "inf" not in flag


def test_too_few_frames_for_k_warns_and_names_the_largest_k():
    """2F below 8K - 3 equations leaves Dai's triplet undetermined (F = 17, K = 6: e_R .15
    on noise-free data, no warning before); F = 17, K = 4 (34 >= 29) is exact and silent."""
    seq = data_tools.make_synthetic(F=17, P=49, K=6, seed=0)
    res, caught = _run(seq.W, 6)
    assert len(caught) == 1 and "W-few-frames: too few frames for K = 6" in res.diagnostics.message
    assert "use K <= 4" in res.diagnostics.message
    assert res.diagnostics.signals["triplet_unknowns"] == 45
    seq = data_tools.make_synthetic(F=17, P=49, K=4, seed=0)
    res, caught = _run(seq.W, 4)
    assert caught == [] and res.errors(seq.shapes, rotations_gt=seq.rotations)["e_R"] < 1e-4

"""Rerun recordings: write .rrd files from small runs, read them back with rerun's chunk reader."""

import dataclasses
from types import SimpleNamespace

import numpy as np
import pytest

rr = pytest.importorskip("rerun")
from rerun.chunk import RrdReader  # noqa: E402

import data_tools  # noqa: E402
import nrsfm  # noqa: E402
from nrsfm.geometry import align_similarity as similarity_align  # noqa: E402
from nrsfm.metrics import camera_alignment  # noqa: E402
from nrsfm.views import build_recording, recording_content, save_recording  # noqa: E402
from rrd_reading import column, read_rrd  # noqa: E402


@pytest.fixture(scope="module")
def seq():
    return data_tools.make_synthetic(F=24, P=15, K=2, motion="smooth", seed=3)


@pytest.fixture(scope="module")
def pinv_result(seq):
    return nrsfm.reconstruct(seq.W, seq.K, method="pseudo_inverse", rotations=seq.rotations)


def _stand_in_stages(result, seq, n_iter=9, seed=0):
    """Objects shaped like RotationResult / ShapeResult, with known arrays."""
    rng = np.random.default_rng(seed)
    K, F = result.K, result.n_frames
    from scipy.spatial.transform import Rotation

    noise = Rotation.from_rotvec(0.02 * rng.standard_normal((K * F, 3))).as_matrix()
    registered = noise.reshape(K, F, 3, 3) @ seq.rotations[None]
    kept = rng.random((K, F)) > 0.3
    kept[0] = True
    rotation_stage = SimpleNamespace(
        rotations=seq.rotations,
        registered=registered,
        per_triplet=registered,
        coefficients=rng.standard_normal((K, F)),
        kept=kept,
        averaged=seq.rotations,
    )
    history = {k: rng.random(n_iter) + 0.1 for k in ("cost", "data_term", "residual", "rho")}
    shape_stage = SimpleNamespace(
        shapes=result.shapes / result.scale,
        X_init=result.X_init / result.scale,
        X_init_singular_values=np.linspace(3, 0.1, F),
        theta=np.linspace(0.01, 1, F),
        history=history,
        n_iter=n_iter,
        converged=True,
        solver="admm",
    )
    return dataclasses.replace(result, rotation_stage=rotation_stage, shape_stage=shape_stage)


def test_pseudo_inverse_recording(tmp_path, seq, pinv_result):
    path = save_recording(pinv_result, tmp_path / "sub" / "pi.rrd", seq, recording_id="t1")
    assert path.is_file() and path.stat().st_size > 0
    reader = RrdReader(path)
    assert [s.recording_id for s in reader.recordings()] == ["t1"]
    assert len(reader.blueprints()) == 1
    data = read_rrd(path)
    F, P = seq.n_frames, seq.n_points
    for p in (
        "/world/shapes/estimate",
        "/world/shapes/ground_truth",
        "/world/cameras/estimate",
        "/world/cameras/ground_truth",
        "/image/measured",
        "/image/reprojected",
        "/errors/e3d",
        "/errors/e_R",
    ):
        rows = sum(b.num_rows for b in data[p]["temporal"])
        assert rows == F, p
        assert all("frame" in b.schema.names for b in data[p]["temporal"])
    for p in (
        "/singular_values/W",
        "/singular_values/X_init",
        "/run/report",
        "/world/trajectory/estimate",
        "/world/trajectory/ground_truth",
    ):
        assert data[p]["static"] and not data[p]["temporal"], p
    # no stages ran: nothing of theirs is logged
    assert not any(
        p.startswith(("/shape_history", "/rotations", "/rotation_samples")) for p in data
    )

    # values: ground truth in its world frame, estimate similarity-aligned onto it
    gt, frames = column(
        data["/world/shapes/ground_truth"]["temporal"], "Points3D:positions", "frame"
    )
    assert np.array_equal(frames, np.arange(F))
    gt = np.asarray(gt)
    world = seq.world_shapes - seq.world_shapes.mean(axis=2, keepdims=True)
    np.testing.assert_allclose(gt, world.transpose(0, 2, 1), atol=1e-5)
    est = np.asarray(
        column(data["/world/shapes/estimate"]["temporal"], "Points3D:positions", "frame")[0]
    )
    np.testing.assert_allclose(
        est, similarity_align(pinv_result.shapes, world).transpose(0, 2, 1), atol=1e-5
    )
    assert est.shape == (F, P, 3)
    e3d = np.asarray(column(data["/errors/e3d"]["temporal"], "Scalars:scalars", "frame")[0])
    np.testing.assert_allclose(
        e3d.ravel(), nrsfm.e3d(pinv_result.shapes, seq.shapes, per_frame=True), rtol=1e-12
    )
    sv = column(data["/singular_values/W"]["static"], "BarChart:values")
    assert sv  # tensor data, checked in content test below
    text = column(data["/run/report"]["static"], "TextDocument:text")[0][0]
    assert "pseudo_inverse" in text and "e3d" in text


def test_stage_recording(tmp_path, seq, pinv_result):
    result = _stand_in_stages(pinv_result, seq)
    path = save_recording(result, tmp_path / "stages.rrd", seq)
    data = read_rrd(path)
    K, F = result.K, result.n_frames
    hist = result.shape_stage.history
    for key in ("cost", "data_term", "residual", "rho"):
        vals, it = column(
            data[f"/shape_history/{key}"]["temporal"], "Scalars:scalars", "shape_iteration"
        )
        assert np.array_equal(it, np.arange(len(hist[key])))
        assert np.array_equal(np.ravel(vals), hist[key])  # float64, exact
    # the same history as static bar charts (visible on any timeline), log10 where it spans
    # decades; nothing of it only on the shape_iteration timeline in the default views
    for key in ("cost", "data_term", "residual", "rho"):
        b = data[f"/shape_history_bars/{key}"]
        assert b["static"] and not b["temporal"], key
        vals = np.asarray(column(b["static"], "BarChart:values")[0][0]["buffer"])
        expect = hist[key] if key == "cost" else np.log10(hist[key])
        np.testing.assert_allclose(vals, expect, rtol=1e-6)
    n_kept = column(data["/rotation_samples/n_kept"]["temporal"], "Scalars:scalars", "frame")[0]
    np.testing.assert_array_equal(np.ravel(n_kept), result.rotation_stage.kept.sum(axis=0))
    theta = np.asarray(
        column(data["/singular_values/log10_theta"]["static"], "BarChart:values")[0][0]["buffer"]
    )
    np.testing.assert_allclose(theta, np.log10(result.shape_stage.theta), rtol=1e-6)
    for k in range(1, K + 1):
        kept = column(
            data[f"/rotation_samples/kept/triplet_{k}"]["temporal"], "Scalars:scalars", "frame"
        )[0]
        assert np.array_equal(np.ravel(kept), result.rotation_stage.kept[k - 1].astype(float))
        coeff = column(
            data[f"/rotation_samples/coefficient/triplet_{k}"]["temporal"],
            "Scalars:scalars",
            "frame",
        )[0]
        assert np.array_equal(np.ravel(coeff), result.rotation_stage.coefficients[k - 1])
        arrows = data[f"/rotations/triplet_{k}"]["temporal"]
        assert sum(b.num_rows for b in arrows) == F
        vecs, _ = column(arrows, "Arrows3D:vectors", "frame")
        Q = camera_alignment(result.rotations, seq.rotations)
        expect = result.rotation_stage.registered[k - 1][:, :2] @ Q
        np.testing.assert_allclose(np.asarray(vecs)[:, :2], expect, atol=1e-6)
    assert sum(b.num_rows for b in data["/rotations/averaged"]["temporal"]) == F
    for name in ("W", "X_init", "theta"):
        assert data[f"/singular_values/{name}"]["static"]
    # the documented top-level paths are exactly those written (all stages ran here)
    from nrsfm.views import ENTITY_PATHS

    tops = {"/" + p.strip("/").split("/")[0] for p in data if not p.startswith("/__")}
    assert tops == set(ENTITY_PATHS)


def test_content_values(seq, pinv_result):
    result = _stand_in_stages(pinv_result, seq)
    c = recording_content(result, seq)
    assert np.array_equal(c.singular_values["W"], result.factorization.singular_values)
    assert np.array_equal(c.singular_values["X_init"], result.shape_stage.X_init_singular_values)
    assert np.array_equal(c.singular_values["theta"], result.shape_stage.theta)
    # cameras align exactly when the estimate is the ground truth up to a global rotation
    np.testing.assert_allclose(c.cameras_est, seq.rotations, atol=1e-10)
    assert c.errors["e_R"] < 1e-10
    # removing the stages: content degrades gracefully
    c0 = recording_content(pinv_result, None)
    assert c0.shapes_gt is None and c0.cameras_gt is None and not c0.admm
    assert c0.triplet_rotations is None and not c0.errors_per_frame
    # the pseudo-inverse shape stage reports its X_init's singular values (the solver's
    # units): those of X_init / scale, to rounding (the trailing ones are ~1e-16 s_1)
    sv = np.linalg.svd(
        (pinv_result.X_init / pinv_result.scale).reshape(seq.n_frames, -1), compute_uv=False
    )
    np.testing.assert_allclose(c0.singular_values["X_init"], sv, rtol=1e-7, atol=1e-12 * sv[0])


def test_no_ground_truth_and_skeleton(tmp_path, seq, pinv_result):
    seq_e = dataclasses.replace(
        seq, rotations=None, world_shapes=None, edges=np.array([[0, 1], [1, 2], [2, 3]])
    )
    path = save_recording(pinv_result, tmp_path / "nogt.rrd", seq_e)
    data = read_rrd(path)
    assert "/world/cameras/ground_truth" not in data and "/errors/e_R" not in data
    strips = data["/world/shapes/ground_truth/skeleton"]["temporal"]
    assert sum(b.num_rows for b in strips) == seq.n_frames
    s = column(strips, "LineStrips3D:strips", "frame")[0]
    assert len(s[0]) == 3 and len(s[0][0]) == 2
    # nothing at all
    data = read_rrd(save_recording(pinv_result, tmp_path / "bare.rrd"))
    assert "/world/shapes/ground_truth" not in data
    assert sum(b.num_rows for b in data["/world/shapes/estimate"]["temporal"]) == seq.n_frames


def test_build_recording_buffers_then_saves(tmp_path, seq, pinv_result):
    rec = build_recording(pinv_result, seq, application_id="nrsfm-test", recording_id="b1")
    path = tmp_path / "late.rrd"
    rec.save(path)
    rec.flush()
    rec.disconnect()
    data = read_rrd(path)
    assert "/world/shapes/estimate" in data and "/run/report" in data


def test_frame_mismatch_raises(seq, pinv_result):
    short = data_tools.make_synthetic(F=10, P=15, K=2, seed=1)
    with pytest.raises(ValueError, match="frames"):
        recording_content(pinv_result, short)


def test_real_shape_stage(tmp_path, seq):
    """Rotations given: the real ADMM shape stage's history ends up on its timeline."""
    res = nrsfm.reconstruct(
        seq.W, seq.K, method="organic", rotations=seq.rotations, shape_solver="admm"
    )
    assert res.rotation_stage is None and res.shape_stage is not None
    data = read_rrd(save_recording(res, tmp_path / "shape.rrd", seq))
    for key in ("cost", "data_term", "residual", "rho"):
        vals, it = column(
            data[f"/shape_history/{key}"]["temporal"], "Scalars:scalars", "shape_iteration"
        )
        assert np.array_equal(np.ravel(vals), np.asarray(res.shape_stage.history[key], float))
        assert len(it) == len(res.shape_stage.history["cost"])
    theta = column(data["/singular_values/theta"]["static"], "BarChart:values")
    assert theta


def test_real_stages_recording(tmp_path, seq):
    """The full pipeline (rotation and shape stages): their arrays end up in the recording.
    Any error of the stages fails this test."""
    res = nrsfm.reconstruct(seq.W, seq.K, method="organic")
    assert res.rotation_stage is not None and res.shape_stage is not None
    data = read_rrd(save_recording(res, tmp_path / "full.rrd", seq))
    F = seq.n_frames
    assert sum(b.num_rows for b in data["/world/shapes/estimate"]["temporal"]) == F
    n = len(res.shape_stage.history["cost"])
    assert n > 0 and sum(b.num_rows for b in data["/shape_history/cost"]["temporal"]) == n
    stage = res.rotation_stage
    assert stage.registered is not None and stage.kept is not None
    K = np.asarray(stage.registered).shape[0]
    assert K == seq.K
    for k in range(1, K + 1):
        assert sum(b.num_rows for b in data[f"/rotations/triplet_{k}"]["temporal"]) == F
        kept = column(
            data[f"/rotation_samples/kept/triplet_{k}"]["temporal"], "Scalars:scalars", "frame"
        )[0]
        assert np.array_equal(np.ravel(kept), np.asarray(stage.kept)[k - 1].astype(float))
        angle = column(
            data[f"/rotation_samples/angle/triplet_{k}"]["temporal"], "Scalars:scalars", "frame"
        )[0]  # the geodesic angle the filter compares with delta
        np.testing.assert_allclose(np.ravel(angle), stage.filter_distance[k - 1], atol=1e-9)
    flips = column(
        data["/rotation_samples/sign_from_smoothness"]["temporal"], "Scalars:scalars", "frame"
    )[0]
    assert np.array_equal(np.ravel(flips), np.asarray(stage.sign_from_smoothness, float))


def test_notebooks_match_their_sources():
    """The committed .ipynb files are regenerated from notebooks/src/*.py (outputs stripped)."""
    import subprocess
    import sys
    from pathlib import Path

    pytest.importorskip("jupytext")
    root = Path(__file__).resolve().parents[1]
    script = root / "notebooks" / "build_notebooks.py"
    if not script.is_file():
        pytest.skip("no notebooks in this checkout")
    out = subprocess.run(
        [sys.executable, str(script), "--check"], capture_output=True, text=True, cwd=root
    )
    assert out.returncode == 0, out.stdout + out.stderr


def test_committed_notebooks_have_no_outputs():
    """Every code cell of every committed notebook is stripped, but those whose output CI
    compares (``# NBVAL_CHECK_OUTPUT``): no outputs, no execution count (``pytest
    --nbval-lax`` runs them; a committed output would be a stale figure)."""
    import json
    from pathlib import Path

    root = Path(__file__).resolve().parents[1]
    sources = sorted((root / "notebooks" / "src").glob("[0-9][0-9]_*.py"))
    if not sources:
        pytest.skip("no notebooks in this checkout")
    notebooks = sorted((root / "notebooks").glob("[0-9][0-9]_*.ipynb"))
    assert [nb.stem for nb in notebooks] == [src.stem for src in sources]
    not_stripped = []
    for nb in notebooks:
        cells = json.loads(nb.read_text())["cells"]
        code = [c for c in cells if c["cell_type"] == "code"]
        assert code, f"{nb.name} has no code cell"
        code = [c for c in code if not "".join(c["source"]).startswith("# NBVAL_CHECK_OUTPUT")]
        not_stripped += [
            f"{nb.name} cell {c.get('id', i)}"
            for i, c in enumerate(code)
            if c.get("outputs") or c.get("execution_count") is not None
        ]
    assert not not_stripped, (
        "committed notebooks with outputs (regenerate them: python "
        f"notebooks/build_notebooks.py): {not_stripped}"
    )


def _views(node):
    import rerun.blueprint as rrb

    if isinstance(node, rrb.View):
        yield node
        return
    for child in getattr(node, "contents", None) or []:
        yield from _views(child)


def _check_views_on_frame(data, views):
    for v in views:
        origin = str(v.origin)
        contents = v.contents if isinstance(v.contents, list) else [origin]
        prefixes = [c.rstrip("/*") for c in contents if not c.startswith("$")] or [origin]
        shown = [p for p in data if any(p == q or p.startswith(q + "/") for q in prefixes)]
        assert shown, f"view {v.name!r} ({origin}) has no entity"
        visible = [
            p
            for p in shown
            if data[p]["static"] or any("frame" in b.schema.names for b in data[p]["temporal"])
        ]
        assert visible, f"view {v.name!r} shows nothing on the frame timeline"


@pytest.mark.parametrize("stages", [True, False])
def test_every_view_has_data_on_the_opening_timeline(tmp_path, seq, pinv_result, stages):
    """Each view of the default blueprint shows entities logged static or on ``frame``."""
    from nrsfm.views import make_blueprint

    result = _stand_in_stages(pinv_result, seq) if stages else pinv_result
    data = read_rrd(save_recording(result, tmp_path / "bp.rrd", seq))
    bp = make_blueprint(recording_content(result, seq))
    assert bp.time_panel is not None
    views = list(_views(bp.root_container))
    assert len(views) >= (15 if stages else 7), [v.name for v in views]
    _check_views_on_frame(data, views)


def _n_threads():
    import os

    try:
        return len(os.listdir("/proc/self/task"))
    except OSError:
        psutil = pytest.importorskip("psutil")
        return psutil.Process().num_threads()


def test_save_recording_threads_bounded(tmp_path, seq, pinv_result):
    """rerun-sdk keeps 2 threads per dropped stream until a sweep: save_recording sweeps."""
    save_recording(pinv_result, tmp_path / "warm.rrd")
    before = _n_threads()
    for i in range(100):
        save_recording(pinv_result, tmp_path / "loop.rrd")
    after = _n_threads()
    assert after <= before + 4, (before, after)


def test_rendered_notebooks_in_sync():
    """docs/notebooks/NN_*.md (executed notebooks with their figures, for readers of the
    repository) exist for every notebook source, were rendered from its current text and
    link only figures that exist. Re-render: python notebooks/build_notebooks.py --render."""
    import hashlib
    import re
    from pathlib import Path

    root = Path(__file__).resolve().parents[1]
    sources = sorted((root / "notebooks" / "src").glob("[0-9][0-9]_*.py"))
    if not sources:
        pytest.skip("no notebooks in this checkout")
    stale = []
    for src in sources:
        page = root / "docs" / "notebooks" / f"{src.stem}.md"
        digest = hashlib.sha256(src.read_bytes()).hexdigest()
        if not page.is_file() or f"sha256={digest}" not in page.read_text().splitlines()[0]:
            stale.append(src.name)
            continue
        text = page.read_text()
        images = re.findall(r"!\[[^\]]*\]\(([^)\s]+\.png)\)", text)
        for img in images:
            assert (page.parent / img).is_file(), (page.name, img)
        if "plt.show()" in src.read_text():
            assert images, f"{page.name} has no figure"
    assert not stale, (
        "rendered notebooks out of date (run python notebooks/build_notebooks.py "
        f"--render): {stale}"
    )


def test_rrd_screenshot_script_errors(tmp_path):
    """tools/rrd_screenshot.py: a missing recording is one error line, no traceback."""
    import subprocess
    import sys
    from pathlib import Path

    script = Path(__file__).resolve().parents[1] / "tools" / "rrd_screenshot.py"
    out = subprocess.run(
        [sys.executable, str(script), str(tmp_path / "none.rrd"), str(tmp_path / "x.png")],
        capture_output=True,
        text=True,
        timeout=60,
    )
    assert out.returncode != 0
    assert "no such recording" in out.stderr and "Traceback" not in out.stderr
    assert not (tmp_path / "x.png").exists()


def test_missing_data_draws_the_filled_points_by_their_reliability(tmp_path):
    """With missing data the recording holds /world/shapes/filled: per frame, the points not
    observed there, coloured from yellow (fill gain 1) to red (gain MAX_GAIN^2), or for the
    points filled from their neighbours by their fills' spread (orange at SPREAD_MAX)."""
    from nrsfm.stages.completion import MAX_GAIN
    from nrsfm.stages.fill import SPREAD_MAX
    from nrsfm.views.recording import fill_colors

    seq = data_tools.make_synthetic(F=40, P=20, K=2, seed=3)
    W, obs = data_tools.drop_tracks(seq.W, 0.3, seed=31, pattern="lost")
    with pytest.warns(nrsfm.NRSfMWarning, match="W-fills-unreliable: "):  # 4 lost tracks
        res = nrsfm.reconstruct(W, 2)
    c = recording_content(res, seq)
    assert "WARNING: W-fills-unreliable: " in c.report
    np.testing.assert_array_equal(c.filled, ~obs)
    np.testing.assert_allclose(c.fill_gain, res.fill_gain)
    path = save_recording(res, tmp_path / "missing.rrd", sequence=seq)
    filled = read_rrd(path)["/world/shapes/filled"]
    positions, frames = column(filled["temporal"], "Points3D:positions", "frame")
    assert [len(p) for p in positions] == list((~obs).sum(axis=1))
    colours = fill_colors(np.array([1.0, MAX_GAIN, MAX_GAIN**2, np.inf]))
    assert colours[0, 1] == 230 and colours[2, 1] == 0 and colours[3, 1] == 0
    assert colours[0, 1] > colours[1, 1] > colours[2, 1]
    by_spread = fill_colors(
        np.array([MAX_GAIN**2, MAX_GAIN**2, 1.0, 1.0]),
        np.array([0.0, SPREAD_MAX, 2 * SPREAD_MAX, np.nan]),
    )
    assert by_spread[0, 1] == 230 and by_spread[2, 1] == 0 and by_spread[3, 1] == 230
    assert by_spread[1, 1] == colours[1, 1]  # orange at either threshold
    np.testing.assert_array_equal(c.fill_spread, res.fill_spread)
    complete = recording_content(nrsfm.reconstruct(seq.W, 2), seq)
    assert complete.filled is None


def test_the_same_run_writes_the_same_recording_id(tmp_path):
    """Two runs of the same reconstruction give recordings with one recording id (their
    bytes differ by the row ids and times Rerun stamps); another run another id."""
    seq = data_tools.make_synthetic(F=20, P=12, K=1, seed=3)
    ids = []
    for i, method in enumerate(("organic", "organic", "bmm")):
        res = nrsfm.reconstruct(seq.W, 1, method=method)
        path = save_recording(res, tmp_path / f"r{i}.rrd", sequence=seq)
        (entry,) = RrdReader(path).recordings()
        ids.append(entry.recording_id)
    assert ids[0] == ids[1] != ids[2]


@pytest.fixture(scope="module")
def perspective_run():
    """Exact pinhole data (3 object radii away) and its perspective reconstruction."""
    cam = data_tools.PerspectiveCamera(distance=3.0)
    s = data_tools.make_synthetic(F=12, P=12, K=1, motion="smooth", seed=2, camera=cam)
    return s, nrsfm.reconstruct(s.W, 1, intrinsics=s.extra["intrinsics"])


def test_perspective_recording(tmp_path, perspective_run):
    """A perspective result: cameras at their centres -R_f' t_f with the intrinsics' frustum,
    shapes as returned, the image in pixels (tracks, orthographic start, perspective), the
    per-frame reprojection RMS and the refinement's history on its own timeline."""
    from nrsfm.views import ENTITY_PATHS, PERSPECTIVE_ENTITY_PATHS, make_blueprint

    s, res = perspective_run
    p, F = res.perspective, s.n_frames
    data = read_rrd(save_recording(res, tmp_path / "persp.rrd", s))
    tops = {"/" + q.strip("/").split("/")[0] for q in data if not q.startswith("/__")}
    assert tops == set(ENTITY_PATHS + PERSPECTIVE_ENTITY_PATHS)
    for q in ("/image/measured", "/image/orthographic", "/image/perspective"):
        assert sum(b.num_rows for b in data[q]["temporal"]) == F, q
    for q in ("/world/cameras/ground_truth", "/image/reprojected", "/world/trajectory/gt"):
        assert q not in data
    assert data["/world/trajectory/estimate"]["static"]
    # the cameras: centres -R_f' t_f, rotations R_f' (camera -> world), the real intrinsics
    cams = data["/world/cameras/estimate"]
    centres, frames = column(cams["temporal"], "Transform3D:translation", "frame")
    assert np.array_equal(frames, np.arange(F))
    expect = -np.einsum("fji,fj->fi", res.rotations, p.translations)
    np.testing.assert_allclose(np.asarray(centres).reshape(F, 3), expect, atol=1e-6)
    K_cam = column(cams["static"], "Pinhole:image_from_camera")[0][0]
    np.testing.assert_allclose(np.reshape(K_cam, (3, 3)).T, s.extra["intrinsics"], rtol=1e-6)
    size = column(cams["static"], "Pinhole:resolution")[0][0]
    np.testing.assert_allclose(size, 2 * s.extra["intrinsics"][:2, 2])
    # the shapes as returned (no per-frame alignment), the truth aligned onto them
    est = column(data["/world/shapes/estimate"]["temporal"], "Points3D:positions", "frame")[0]
    np.testing.assert_allclose(np.asarray(est), res.shapes.transpose(0, 2, 1), atol=1e-6)
    gt = column(data["/world/shapes/ground_truth"]["temporal"], "Points3D:positions", "frame")
    np.testing.assert_allclose(np.asarray(gt[0]), np.asarray(est), atol=1e-6)  # exact data
    # the refinement's history: its own timeline, exact; log10 bars (static)
    for key in ("cost", "data_term"):
        vals, it = column(
            data[f"/perspective_history/{key}"]["temporal"],
            "Scalars:scalars",
            "perspective_iteration",
        )
        assert np.array_equal(it, np.arange(p.n_iter + 1))
        assert np.array_equal(np.ravel(vals), p.history[key])
        bars = data[f"/perspective_history_bars/{key}"]
        assert bars["static"] and not bars["temporal"]
        vals = np.asarray(column(bars["static"], "BarChart:values")[0][0]["buffer"])
        np.testing.assert_allclose(vals, np.log10(p.history[key]), rtol=1e-6)
    # the layout: every view has data on the opening timeline
    bp = make_blueprint(recording_content(res, s))
    views = list(_views(bp.root_container))
    assert {str(v.origin) for v in views} >= {"/world", "/image", "/reprojection"}
    _check_views_on_frame(data, views)
    text = column(data["/run/report"]["static"], "TextDocument:text")[0][0]
    assert "## Perspective refinement" in text and "(px)" in text


def test_perspective_reprojection_is_the_tracks_on_exact_data(tmp_path, perspective_run):
    """On exact pinhole data /image/perspective is /image/measured (the tracks W, pixels);
    the orthographic start's projection is pixels off; the per-frame RMS says so."""
    s, res = perspective_run
    F, P = s.n_frames, s.n_points
    data = read_rrd(save_recording(res, tmp_path / "exact.rrd", s))
    image = {}
    for name in ("measured", "orthographic", "perspective"):
        pts, frames = column(data[f"/image/{name}"]["temporal"], "Points2D:positions", "frame")
        assert np.array_equal(frames, np.arange(F))
        image[name] = np.asarray(pts).reshape(F, P, 2)
    tracks = s.W.reshape(F, 2, P).transpose(0, 2, 1)
    np.testing.assert_allclose(image["measured"], tracks, atol=1e-4)  # float32 pixels
    np.testing.assert_allclose(image["perspective"], tracks, atol=1e-4)
    assert np.abs(image["orthographic"] - tracks).max() > 1.0
    rms = {}
    for name in ("orthographic", "perspective"):
        v, _ = column(data[f"/reprojection/{name}"]["temporal"], "Scalars:scalars", "frame")
        rms[name] = np.ravel(v)
    assert rms["perspective"].max() < 1e-6 and rms["orthographic"].min() > 0.1
    total = np.sqrt(np.mean(rms["orthographic"] ** 2))  # every point seen in every frame
    np.testing.assert_allclose(total, res.perspective.reprojection_before, rtol=1e-9)


def test_perspective_frusta_take_the_image_size_where_known(tmp_path, perspective_run):
    """The frustum's image is the input's size where known (``image_size`` (H, W), as
    ``nrsfm track`` writes it; ``nrsfm run`` passes it on), else twice the principal point."""
    from nrsfm.cli import main

    s, res = perspective_run
    assert recording_content(res, s).image_size == (640.0, 480.0)  # principal (320, 240)
    assert recording_content(res, s, image_size=(500, 700)).image_size == (700.0, 500.0)
    sized = dataclasses.replace(s, extra=dict(s.extra, image_size=(400, 600)))
    assert recording_content(res, sized).image_size == (600.0, 400.0)
    inp, rrd = tmp_path / "t.npz", tmp_path / "t.rrd"
    np.savez(inp, W=s.W, K=1, image_size=np.array([500, 700]), tracks=np.zeros(1))
    args = ["run", inp, "-o", tmp_path / "o.npz", "--rrd", rrd, "--quiet", "--focal", "800"]
    assert main(list(map(str, args + ["--principal", "320", "240"]))) == 0
    cams = read_rrd(rrd)["/world/cameras/estimate"]["static"]
    np.testing.assert_allclose(column(cams, "Pinhole:resolution")[0][0], [700, 500])

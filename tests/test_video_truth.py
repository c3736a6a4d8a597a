"""The synthetic video on disk with its ground truth, its score, ``nrsfm demo --video`` and
``nrsfm video --ground-truth`` (tiny videos: each test takes about a second)."""

import re
from types import SimpleNamespace

import numpy as np
import pytest

cv2 = pytest.importorskip("cv2")

import data_tools as dt  # noqa: E402
import nrsfm  # noqa: E402
from nrsfm.cli import main  # noqa: E402
from nrsfm.tracks import reconstruct_tracks  # noqa: E402


@pytest.fixture(scope="module")
def video():
    return dt.make_video("sheet", n_frames=8, size=(96, 128), grid=13, seed=1)


def test_written_video_and_ground_truth_read_back(tmp_path, video):
    frames, truth = dt.write_video(video, tmp_path / "v")
    assert sorted(p.name for p in frames.iterdir())[:2] == ["000000.png", "000001.png"]
    assert np.array_equal(dt.load_frames(frames), video.frames)  # lossless
    loaded = dt.load_ground_truth(truth)
    assert loaded.frames is None and loaded.n_frames == 8 and loaded.surface == "sheet"
    tracks = dt.track_sparse(video.frames, detect_every=2).tracks
    a, b = video.ground_truth(tracks), loaded.ground_truth(tracks)
    assert a["valid"].sum() > 20 and np.array_equal(a["valid"], b["valid"])
    np.testing.assert_allclose(a["camera"], b["camera"], rtol=0, atol=1e-12)


def test_score_of_a_perfect_and_of_a_wrong_reconstruction(video):
    """Scored on the used tracks that started on the surface, column for column."""
    T = dt.track_sparse(video.frames).tracks
    T[:, :, 0] = 2.0  # a track on the background: no truth
    gt = video.ground_truth(T)
    used = np.isfinite(T).all(axis=(0, 1))
    shapes = np.nan_to_num(video.pixel_scale * gt["world"][:, :, used])  # 0: no truth
    vr = SimpleNamespace(
        used=used, result=SimpleNamespace(shapes=shapes, rotations=video.rotations)
    )
    sc = dt.score_tracks(video, T, vr)
    assert used[0] and not gt["valid"][0]
    assert sc["n_used"] == used.sum() and sc["n_scored"] == (used & gt["valid"]).sum()
    assert sc["e3d"] < 1e-9 and sc["e3d_akhter"] < 1e-9 and sc["e_R"] < 1e-9
    rng = np.random.default_rng(0)
    vr.result.shapes = shapes[:, :, rng.permutation(shapes.shape[2])]
    assert dt.score_tracks(video, T, vr)["e3d"] > 0.1


def test_ground_truth_file_errors(tmp_path, video):
    (tmp_path / "text.npz").write_text("not a ground truth\n")
    with pytest.raises(ValueError, match="it is a text file") as info:
        dt.load_ground_truth(tmp_path / "text.npz")
    assert "pickle" not in str(info.value)
    np.savez(tmp_path / "other.npz", W=np.zeros(3))
    with pytest.raises(ValueError, match=r"has no format .* \(found arrays: \['W'\]\)"):
        dt.load_ground_truth(tmp_path / "other.npz")
    with pytest.raises(ValueError, match="has no frames"):
        dt.write_video(
            dt.load_ground_truth(dt.save_ground_truth(video, tmp_path / "g.npz")), tmp_path / "v"
        )


def test_demo_video_scores_the_tracks_of_nrsfm_video(tmp_path, monkeypatch, capsys):
    """``nrsfm demo --video`` writes the video, runs ``nrsfm video --ground-truth`` and
    prints e3d; the Python route on the same frames (nrsfm video's tracking settings:
    sparse, new tracks every 5 frames) gives the same tracks and the same score."""
    monkeypatch.setenv("NRSFM_OUT", str(tmp_path))
    assert (
        main(["demo", "--video", "--frames", "12", "--size", "120x160", "--seed", "1", "--quiet"])
        == 0
    )
    out = capsys.readouterr().out
    assert f"running: nrsfm video {tmp_path / 'demo_video' / 'frames'} --ground-truth " in out
    printed = re.search(
        r"\((\d+) of the (\d+) used tracks.*e3d ([\d.]+), e3d \(Akhter\) "
        r"([\d.]+), e_R ([\d.]+)",
        out,
    )
    assert printed, out
    frames = dt.load_frames(tmp_path / "demo_video" / "frames")
    truth = dt.load_ground_truth(tmp_path / "demo_video" / "ground_truth.npz")
    assert frames.shape == (12, 120, 160, 3) and truth.n_frames == 12
    tracks = dt.track_sparse(frames, max_points=2000, detect_every=5)
    with pytest.warns(nrsfm.NRSfMWarning, match="W-fills-unreliable: "):  # late tracks
        vr = reconstruct_tracks(tracks.W, 1, seed=1, progress=False)
    sc = dt.score_tracks(truth, tracks, vr)
    assert printed.groups() == (
        str(sc["n_scored"]),
        str(sc["n_used"]),
        f"{sc['e3d']:.4f}",
        f"{sc['e3d_akhter']:.4f}",
        f"{sc['e_R']:.4f}",
    )
    assert sc["e3d"] < 0.5


def test_video_ground_truth_saved_with_output_and_checked(tmp_path, video, capsys):
    frames, truth = dt.write_video(video, tmp_path / "v")
    res = tmp_path / "res.npz"
    # no late tracks (--detect-every 0): the completion converges, so the run prints no
    # warning (with late tracks it stops at its cap: tests/test_video.py)
    assert (
        main(
            [
                "video",
                str(frames),
                "--ground-truth",
                str(truth),
                "-o",
                str(res),
                "--detect-every",
                "0",
                "--quiet",
            ]
        )
        == 0
    )
    assert "errors against ground truth (" in capsys.readouterr().out
    with np.load(res) as z:
        assert 0 < float(z["e3d"]) < 1 and int(z["n_scored"]) <= int(z["used"].sum())
    with pytest.raises(SystemExit):
        main(["video", str(frames), "--ground-truth", str(truth), "--max-frames", "5", "--quiet"])
    assert "has 8 frames but 5 were read" in capsys.readouterr().err


def test_video_only_flags_need_video(capsys):
    for flag, value in (("--frames", "5"), ("--size", "64x64"), ("--surface", "face")):
        with pytest.raises(SystemExit) as exc:
            main(["demo", flag, value])
        assert exc.value.code == 2
        assert f"{flag}: only with --video" in capsys.readouterr().err
    with pytest.raises(SystemExit):
        main(["demo", "--video", "--size", "64by64"])
    assert "expected HEIGHTxWIDTH" in capsys.readouterr().err


def test_pinhole_ground_truth_reads_back_with_its_camera(tmp_path):
    cam = dt.PerspectiveCamera(distance=3.0, focal=120.0)
    video = dt.make_video("sheet", n_frames=6, size=(96, 128), grid=13, seed=1, camera=cam)
    _, truth = dt.write_video(video, tmp_path / "p")
    loaded = dt.load_ground_truth(truth)
    assert loaded.camera == video.camera and loaded.camera.principal == (64.0, 48.0)
    np.testing.assert_array_equal(loaded.translations, video.translations)
    np.testing.assert_array_equal(loaded.extra["intrinsics"], video.intrinsics)
    T = video.project(video.vertices)[:, :, ::5]
    a, b = video.ground_truth(T), loaded.ground_truth(T)
    np.testing.assert_allclose(b["camera"], a["camera"], rtol=0, atol=1e-12)
    np.testing.assert_allclose(b["pixels"], T, atol=1e-6)
    data = dict(np.load(truth))
    del data["translations"]
    np.savez(tmp_path / "bad.npz", **data)
    with pytest.raises(ValueError, match="pinhole camera needs"):
        dt.load_ground_truth(tmp_path / "bad.npz")

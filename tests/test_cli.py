"""The command line: outputs written exactly where asked, and every failure one line.

Each failure runs ``python -m nrsfm`` in a subprocess (about 0.5 s each) and checks: a
non-zero exit, exactly one line on stderr, no traceback.
"""

import hashlib
import os
import resource
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import scipy.io

import data_tools as dt
from nrsfm import __version__
from nrsfm.cli import COMMANDS, build_parser, main

ROOT = Path(__file__).resolve().parents[1]


def nrsfm(*args, cwd, preexec_fn=None, env_extra=None):
    env = dict(
        os.environ,
        PYTHONPATH=str(ROOT),
        PWD=str(cwd),
        OMP_NUM_THREADS="1",
        OPENBLAS_NUM_THREADS="1",
        MKL_NUM_THREADS="1",
    )
    env.pop("NRSFM_DEBUG", None)
    env.update(env_extra or {})
    return subprocess.run(
        [sys.executable, "-m", "nrsfm", *map(str, args)],
        cwd=cwd,
        env=env,
        capture_output=True,
        text=True,
        preexec_fn=preexec_fn,
        timeout=120,
    )


def assert_one_line_failure(proc, *fragments, code=None):
    lines = proc.stderr.splitlines()
    assert proc.returncode != 0, proc.stdout
    if code is not None:
        assert proc.returncode == code, proc.stderr
    assert "Traceback" not in proc.stderr + proc.stdout
    assert len(lines) == 1, proc.stderr
    assert lines[0].startswith("nrsfm"), lines
    for frag in fragments:
        assert frag in lines[0], lines[0]


def digest(path):
    return hashlib.sha256(Path(path).read_bytes()).hexdigest()


@pytest.fixture(scope="module")
def seq():
    return dt.make_synthetic(F=30, P=20, K=2, seed=4)


@pytest.fixture()
def good(tmp_path, seq):
    path = tmp_path / "seq.npz"
    np.savez(path, W=seq.W, K=2, shapes=seq.shapes, rotations=seq.rotations)
    return path


# --------------------------------------------------------------------------- success


def test_help_lists_subcommands(capsys):
    with pytest.raises(SystemExit) as exc:
        main(["--help"])
    assert exc.value.code == 0
    out = capsys.readouterr().out
    for cmd in ("demo", "run", "mocap"):
        assert cmd in out


def test_version(tmp_path):
    proc = nrsfm("--version", cwd=tmp_path)
    assert proc.returncode == 0 and proc.stdout.strip() == f"nrsfm {__version__}"


def test_registrations_build_the_parser():
    assert len(COMMANDS) >= 3
    sub = next(a for a in build_parser()._actions if a.dest == "command")
    assert {"demo", "run", "mocap"} <= set(sub.choices)


def test_run_writes_exactly_the_path_given(tmp_path, good, seq, capsys):
    out = tmp_path / "result.npz"
    assert (
        main(
            [
                "run",
                str(good),
                "-o",
                str(out),
                "--method",
                "pseudo_inverse",
                "--given-rotations",
                "--quiet",
            ]
        )
        == 0
    )
    text = capsys.readouterr().out
    assert f"wrote {out}\n" in text and "e3d" in text
    assert sorted(p.name for p in tmp_path.iterdir()) == ["result.npz", "seq.npz"]
    with np.load(out) as z:
        assert z["shapes"].shape == (30, 3, 20)
        np.testing.assert_allclose(z["rotations"], seq.rotations)
        assert int(z["K"]) == 2 and str(z["method"]) == "pseudo_inverse"
        assert {"W", "X_init", "row_means", "scale", "version", "e3d", "e3d_akhter", "e_R"} <= set(
            z.files
        )


def test_run_default_output_and_full_keys(tmp_path, good):
    assert main(["run", str(good), "--quiet"]) == 0
    with np.load(tmp_path / "seq_nrsfm.npz") as z:
        keys = set(z.files)
    assert {
        "shape_cost",
        "shape_data_term",
        "shape_grad_norm",
        "G",
        "per_triplet_rotations",
        "kept",
    } <= keys


def test_ignored_arrays_give_a_one_line_warning(tmp_path, seq):
    path = tmp_path / "extra.npz"
    np.savez(path, W=seq.W, K=2, colour=np.zeros(3))
    proc = nrsfm("run", path, "--quiet", "--method", "pseudo_inverse", cwd=tmp_path)
    assert proc.returncode == 0, proc.stderr
    assert proc.stderr.splitlines() == [
        f"nrsfm: warning: W-ignored-arrays: nrsfm run ignores arrays of {path} that it does "
        f"not read: ['colour'] (it reads W, K, shapes, rotations, edges); rename one if it "
        f"was meant as input"
    ]


def test_float_integral_K_in_file_is_accepted(tmp_path, seq):
    path = tmp_path / "k.npz"
    np.savez(path, W=seq.W, K=2.0)
    assert main(["run", str(path), "--quiet", "--method", "pseudo_inverse"]) == 0


def test_run_reads_a_mat_file_with_W(tmp_path, seq):
    path = tmp_path / "w.mat"
    scipy.io.savemat(path, dict(W=seq.W, K=2))
    assert main(["run", str(path), "--quiet"]) == 0
    with np.load(tmp_path / "w_nrsfm.npz") as z:
        assert z["shapes"].shape == seq.shapes.shape and int(z["K"]) == 2


@pytest.mark.parametrize("layout", ["akhter", "torresani"])
def test_run_reads_the_benchmark_layouts_with_their_ground_truth(tmp_path, seq, layout):
    """The MoCap files' layouts: Akhter et al. (W, S interleaved per frame, Rs) and
    Torresani et al. (P3_gt, stacked by coordinate); errors against their ground truth."""
    F, P = seq.shapes.shape[0], seq.shapes.shape[2]
    if layout == "akhter":
        world = seq.rotations.transpose(0, 2, 1) @ seq.shapes
        arrays = dict(W=seq.W, S=world.reshape(3 * F, P), Rs=seq.rotations[:, :2].reshape(2 * F, 3))
    else:
        arrays = dict(P3_gt=seq.shapes.transpose(1, 0, 2).reshape(3 * F, P))
    path = tmp_path / f"{layout}.mat"
    scipy.io.savemat(path, arrays)
    assert main(["run", str(path), "--K", "2", "--quiet"]) == 0
    with np.load(tmp_path / f"{layout}_nrsfm.npz") as z:
        assert float(z["e3d"]) < 1e-6  # noise-free: exact
        assert ("e_R" in z.files) == (layout == "akhter")


def test_run_leaves_out_tracks_seen_in_one_frame(tmp_path, seq, capsys):
    """What nrsfm track writes: tracks lost at once (seen in 1 frame) are not used, counted,
    and marked in the output; the ground truth and the skeleton follow the tracks used."""
    W = seq.W.copy()
    W[2:, [3, 7]] = np.nan  # tracks 3 and 7: seen in frame 0 only
    edges = np.array([[0, 1], [1, 3], [2, 4], [7, 8]])
    path = tmp_path / "tracks.npz"
    np.savez(path, W=W, K=2, shapes=seq.shapes, edges=edges, tracks=W, lost_at=np.zeros(20))
    assert main(["run", str(path), "--quiet"]) == 0
    assert "2 of 20 tracks seen in fewer than 2 frames not used" in capsys.readouterr().out
    with np.load(tmp_path / "tracks_nrsfm.npz") as z:
        assert z["shapes"].shape == (30, 3, 18) and z["used_points"].sum() == 18
        assert not z["used_points"][[3, 7]].any() and "e3d" in z.files


def test_rrd_without_path_goes_to_the_users_out_folder(tmp_path):
    proc = nrsfm("demo", "--rrd", "--quiet", "--method", "pseudo_inverse", cwd=tmp_path)
    assert proc.returncode == 0, proc.stderr
    assert (tmp_path / "out" / "demo.rrd").stat().st_size > 0


@pytest.mark.parametrize("factor", [1e153, 1e-165])
def test_any_finite_scale(tmp_path, seq, factor):
    path = tmp_path / "scaled.npz"
    np.savez(path, W=seq.W * factor, K=2, shapes=seq.shapes * factor, rotations=seq.rotations)
    out = tmp_path / "o.npz"
    assert main(["run", str(path), "-o", str(out), "--quiet"]) == 0
    ref = tmp_path / "ref.npz"
    np.savez(ref, W=seq.W, K=2)
    assert main(["run", str(ref), "-o", str(tmp_path / "r.npz"), "--quiet"]) == 0
    with np.load(out) as z, np.load(tmp_path / "r.npz") as r:
        assert np.all(np.isfinite(z["shapes"]))
        np.testing.assert_allclose(
            z["shapes"] / factor, r["shapes"], rtol=0, atol=1e-6 * np.abs(r["shapes"]).max()
        )
        assert z["e3d"] < 0.1


# --------------------------------------------------------------------------- failures


def _write(tmp_path, name, **arrays):
    path = tmp_path / name
    np.savez(path, **arrays)
    return path


def _text(tmp_path, content):
    path = tmp_path / f"k{hashlib.sha256(content.encode()).hexdigest()[:8]}.txt"
    path.write_text(content)
    return path


def _bad_inputs(tmp_path, seq, good):
    """name -> (argument list, fragment expected in the message)."""
    (tmp_path / "empty.npz").write_bytes(b"")
    (tmp_path / "corrupt.npz").write_bytes(good.read_bytes()[:300])
    raw = bytearray(good.read_bytes())
    raw[200:260] = b"\0" * 60  # damaged member data, valid zip layout
    (tmp_path / "damaged.npz").write_bytes(bytes(raw))
    np.save(tmp_path / "w.npy", seq.W)
    (tmp_path / "text.npz").write_text("W = 1, 2, 3\n")
    obj = tmp_path / "obj.npz"
    np.savez(obj, W=np.array([1, "a", None], dtype=object), K=1)
    return {
        "missing": (["run", tmp_path / "nope.npz"], "not found"),
        "folder input": (["run", tmp_path], "is a folder"),
        "empty": (["run", tmp_path / "empty.npz"], "is empty"),
        "corrupt": (["run", tmp_path / "corrupt.npz"], "corrupt"),
        "damaged": (["run", tmp_path / "damaged.npz"], "damaged.npz"),
        "text": (["run", tmp_path / "text.npz"], "not an .npz archive, it is a text file"),
        "npy": (["run", tmp_path / "w.npy"], ".npy"),
        "object": (["run", obj], "object array"),
        "no W": (["run", _write(tmp_path, "x.npz", X=np.zeros(3))], "no array 'W'"),
        "no K": (["run", _write(tmp_path, "nok.npz", W=seq.W)], "--K"),
        "K list": (["run", _write(tmp_path, "kl.npz", W=seq.W, K=[2, 3])], "shape (2,)"),
        "K two": (["run", _write(tmp_path, "kt.npz", W=seq.W, K="two")], "'two'"),
        "K 2.7": (["run", _write(tmp_path, "k27.npz", W=seq.W, K=2.7)], "2.7"),
        "K bool": (["run", _write(tmp_path, "kb.npz", W=seq.W, K=True)], "integer"),
        "K too big": (["run", good, "--K", "100"], "too large"),
        "--K 0": (["run", good, "--K", "0"], "at least 1"),
        "--K 2.7": (["run", good, "--K", "2.7"], "2.7"),
        "--K -1": (["run", good, "--K=-1"], "at least 1"),
        "--seed -1": (["run", good, "--seed=-1"], "non-negative"),
        "W strings": (
            ["run", _write(tmp_path, "ws.npz", W=np.array([["a"] * 5] * 4), K=1)],
            "W must hold real numbers; got dtype <U1 (strings)",
        ),
        "W nan": (
            ["run", _write(tmp_path, "nan.npz", W=np.full((10, 6), np.nan), K=1)],
            "observes 0 points",
        ),
        "W 1-D": (["run", _write(tmp_path, "w1.npz", W=np.zeros(10), K=1)], "(2F, P)"),
        "W constant": (["run", _write(tmp_path, "wc.npz", W=np.ones((10, 6)), K=1)], "constant"),
        "shapes points": (
            ["run", _write(tmp_path, "sp.npz", W=seq.W, K=2, shapes=seq.shapes[:, :, :5])],
            "5 points",
        ),
        "shapes frames": (
            ["run", _write(tmp_path, "sf.npz", W=seq.W, K=2, shapes=seq.shapes[:3])],
            "3 frames",
        ),
        "shapes 2-D": (
            ["run", _write(tmp_path, "s2.npz", W=seq.W, K=2, shapes=seq.W)],
            "(F, 3, P)",
        ),
        "rotations bad": (
            ["run", _write(tmp_path, "rb.npz", W=seq.W, K=2, rotations=seq.rotations * 2)],
            "orthonormal",
        ),
        "edges bad": (
            ["run", _write(tmp_path, "eb.npz", W=seq.W, K=2, edges=np.array([[0, 99]]))],
            "edges",
        ),
        "given rotations absent": (
            ["run", _write(tmp_path, "nr.npz", W=seq.W, K=2), "--given-rotations"],
            "rotations",
        ),
        "principal without focal": (["run", good, "--principal", "1", "2"], "with --focal"),
        "focal without principal": (["run", good, "--focal", "800"], "--principal CX CY"),
        "focal 0": (["run", good, "--focal", "0"], "positive"),
        "intrinsics missing": (["run", good, "--intrinsics", tmp_path / "k.txt"], "cannot read"),
        "intrinsics 8 numbers": (["run", good, "--intrinsics", _text(tmp_path, "1 " * 8)], "9"),
        "intrinsics not upper": (
            ["run", good, "--intrinsics", _text(tmp_path, "1 0 0 1 1 0 0 0 1")],
            "upper triangular",
        ),
        "camera and given rotations": (
            ["run", good, "--focal", "800", "--principal", "0", "0", "--given-rotations"],
            "one or the other",
        ),
        "output is a folder": (["run", good, "-o", tmp_path], "existing folder"),
        "output not .npz": (["run", good, "-o", tmp_path / "o.txt"], "name it so"),
        "output folder missing": (["run", good, "-o", tmp_path / "no" / "o.npz"], "does not exist"),
        "output read-only folder": (["run", good, "-o", "/sys/o.npz"], "not writable"),
        "output is the input": (["run", good, "-o", good], "overwrite the input"),
        "rrd unwritable": (["run", good, "--rrd", "/sys/o.rrd"], "not writable"),
        "rrd folder missing": (["demo", "--rrd", tmp_path / "no" / "d.rrd"], "does not exist"),
        "rrd is a folder": (["demo", "--rrd", tmp_path / "f.rrd"], "existing folder"),
        "rrd suffix": (["demo", "--rrd", tmp_path / "d.txt"], ".rrd"),
        "unknown method": (["demo", "--method", "magic"], "invalid choice"),
        "no command": ([], "required"),
        "unknown sequence": (["mocap", "juggling", "--data", tmp_path], "unknown MoCap"),
        "mocap folder missing": (["mocap", "drink", "--data", tmp_path / "none"], "not found"),
    }


CASES = [
    "missing",
    "folder input",
    "empty",
    "corrupt",
    "damaged",
    "text",
    "npy",
    "object",
    "no W",
    "no K",
    "K list",
    "K two",
    "K 2.7",
    "K bool",
    "K too big",
    "--K 0",
    "--K 2.7",
    "--K -1",
    "--seed -1",
    "W strings",
    "W nan",
    "W 1-D",
    "W constant",
    "shapes points",
    "shapes frames",
    "shapes 2-D",
    "rotations bad",
    "edges bad",
    "given rotations absent",
    "principal without focal",
    "focal without principal",
    "focal 0",
    "intrinsics missing",
    "intrinsics 8 numbers",
    "intrinsics not upper",
    "camera and given rotations",
    "output is a folder",
    "output not .npz",
    "output folder missing",
    "output read-only folder",
    "output is the input",
    "rrd unwritable",
    "rrd folder missing",
    "rrd is a folder",
    "rrd suffix",
    "unknown method",
    "no command",
    "unknown sequence",
    "mocap folder missing",
]


@pytest.mark.parametrize("case", CASES)
def test_failure_is_one_line(tmp_path, seq, good, case):
    if "/sys" in str(_bad_inputs(tmp_path, seq, good)[case][0]) and not os.path.isdir("/sys"):
        pytest.skip("needs Linux's read-only /sys")
    (tmp_path / "f.rrd").mkdir()
    args, fragment = _bad_inputs(tmp_path, seq, good)[case]
    before = sorted(p.name for p in tmp_path.iterdir())
    proc = nrsfm(*args, cwd=tmp_path)
    assert_one_line_failure(proc, fragment)
    assert "allow_pickle" not in proc.stderr and "unsafe" not in proc.stderr
    # checked before the computation: no progress, no output, nothing new on disk
    assert proc.stdout == ""
    assert sorted(p.name for p in tmp_path.iterdir()) == before


def test_read_only_folder_by_permissions(tmp_path, good):
    if os.geteuid() == 0:
        pytest.skip("root writes into read-only folders (the /sys case covers it)")
    ro = tmp_path / "ro"
    ro.mkdir()
    ro.chmod(0o555)
    try:
        assert_one_line_failure(
            nrsfm("run", good, "-o", ro / "o.npz", cwd=tmp_path), "not writable"
        )
    finally:
        ro.chmod(0o755)


def test_mocap_without_data_folder(tmp_path):
    env = {k: v for k, v in os.environ.items() if k != "NRSFM_DATA"}
    proc = subprocess.run(
        [sys.executable, "-m", "nrsfm", "mocap", "pickup"],
        cwd=tmp_path,
        env=dict(env, PYTHONPATH=str(ROOT), PWD=str(tmp_path)),
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert_one_line_failure(proc, "NRSFM_DATA", "--data", code=2)


@pytest.mark.parametrize("form", ["parent", "mocap"])
def test_mocap_data_folder_both_forms(tmp_path, form):
    """``--data`` and ``NRSFM_DATA`` take the folder that holds mocap/ or mocap/ itself."""
    folder = tmp_path / "data" / "mocap"
    folder.mkdir(parents=True)
    scipy.io.savemat(
        folder / "shark.mat", {"P3_gt": np.random.default_rng(0).standard_normal((30, 12))}
    )
    given = folder.parent if form == "parent" else folder
    for args, env in (((("--data", given)), None), ((), {"NRSFM_DATA": str(given)})):
        proc = nrsfm("mocap", "shark", *args, "--K", "1", "--quiet", cwd=tmp_path, env_extra=env)
        assert proc.returncode == 0, proc.stderr
        assert "errors against ground truth: e3d" in proc.stdout


def test_mocap_missing_file_names_the_folder_to_use(tmp_path):
    (tmp_path / "data" / "mocap").mkdir(parents=True)
    scipy.io.savemat(tmp_path / "data" / "mocap" / "pickup.mat", {"W": np.zeros((2, 2))})
    proc = nrsfm("mocap", "pickup", "--data", tmp_path, cwd=tmp_path)
    assert_one_line_failure(
        proc,
        f"looked in {tmp_path / 'mocap'} (no such folder) and {tmp_path};",
        f"{tmp_path / 'data'} holds it",
        code=1,
    )


def test_given_rotations_without_ground_truth_on_mocap(tmp_path):
    folder = tmp_path / "mocap"
    folder.mkdir()
    scipy.io.savemat(
        folder / "shark.mat", {"P3_gt": np.random.default_rng(0).standard_normal((30, 12))}
    )
    proc = nrsfm("mocap", "shark", "--data", folder, "--given-rotations", cwd=tmp_path)
    assert_one_line_failure(proc, "no ground-truth rotations", code=2)
    proc = nrsfm("mocap", "shark", "--data", folder, "--K", "100", cwd=tmp_path)
    assert_one_line_failure(proc, "too large")


def _corrupt_mat_files(folder, good_mat):
    folder.mkdir()
    (folder / "drink.mat").write_bytes(b"")  # MatReadError
    (folder / "pickup.mat").write_bytes(good_mat[:5000])  # truncated
    (folder / "yoga.mat").write_bytes(np.random.default_rng(0).bytes(4096))
    scipy.io.savemat(folder / "stretch.mat", {"X": np.zeros(3)})  # KeyError
    scipy.io.savemat(folder / "dance.mat", {"W": np.zeros((10, 4)), "S": np.zeros((3, 4))})
    scipy.io.savemat(folder / "shark.mat", {"P3_gt": np.zeros((7, 4))})  # IndexError-like
    scipy.io.savemat(folder / "face.mat", {"P3_gt": np.array(["ab"])})
    scipy.io.savemat(folder / "walking.mat", {"P3_gt": np.full((9, 4), np.nan)})


@pytest.mark.parametrize("name", dt.MOCAP_NAMES)
def test_corrupt_mat_files(tmp_path, name):
    rng = np.random.default_rng(1)
    buf = tmp_path / "valid.mat"
    scipy.io.savemat(buf, {"W": rng.standard_normal((40, 30)), "S": rng.standard_normal((60, 30))})
    _corrupt_mat_files(tmp_path / "mocap", buf.read_bytes())
    proc = nrsfm("mocap", name, "--data", tmp_path / "mocap", cwd=tmp_path)
    assert_one_line_failure(proc, f"{name}.mat", code=1)


def test_failed_writes_leave_existing_outputs_byte_identical(tmp_path, good):
    out, rrd = tmp_path / "result.npz", tmp_path / "rec.rrd"
    proc = nrsfm(
        "run", good, "-o", out, "--rrd", rrd, "--quiet", "--method", "pseudo_inverse", cwd=tmp_path
    )
    assert proc.returncode == 0, proc.stderr
    before = {p: digest(p) for p in (out, rrd)}

    def limit_to(nbytes):
        return lambda: resource.setrlimit(resource.RLIMIT_FSIZE, (nbytes, nbytes))

    # other settings than the first run: the new content would differ from the old
    proc = nrsfm(
        "run",
        good,
        "-o",
        out,
        "--quiet",
        cwd=tmp_path,
        preexec_fn=limit_to(out.stat().st_size // 2),
    )
    assert_one_line_failure(proc, str(out), code=1)
    proc = nrsfm(
        "demo",
        "--rrd",
        rrd,
        "--quiet",
        "--method",
        "pseudo_inverse",
        cwd=tmp_path,
        preexec_fn=limit_to(rrd.stat().st_size // 2),
    )
    assert_one_line_failure(proc, str(rrd), code=1)
    assert {p: digest(p) for p in (out, rrd)} == before
    leftovers = [p.name for p in tmp_path.iterdir() if p.name.startswith(".")]
    assert leftovers == []


@pytest.mark.parametrize(
    "args, fragment",
    [
        (["video", "v.avi", "--K", "0"], "--K"),
        (["video", "v.avi", "--seed", "-1"], "--seed"),
        (["video", "v.avi", "--step", "0"], "--step"),
        (["track", "v.avi", "--max-frames", "x"], "--max-frames"),
        (["benchmark", "--out", "o", "--workers", "0"], "--workers"),
        (["benchmark", "--out", "o", "--seed", "-2"], "--seed"),
        (["video", "v.avi", "--rrd", "v.txt"], ".rrd"),
    ],
)
def test_every_subcommand_checks_arguments_the_same_way(tmp_path, args, fragment):
    """One set of validators and one exit status (2) for a bad command line, in every
    subcommand; checked before any work (the video file does not exist)."""
    proc = nrsfm(*args, cwd=tmp_path)
    assert_one_line_failure(proc, fragment, code=2)


def test_help_documents_the_exit_status(capsys):
    with pytest.raises(SystemExit):
        main(["--help"])
    assert "Exit status: 0 success, 1 error" in " ".join(capsys.readouterr().out.split())


def test_core_does_not_import_data_tools():
    """Dependencies one way: only the CLI and the experiment runner use data_tools."""
    import re

    top = {"cli", "experiments"}
    offenders = []
    for path in (ROOT / "nrsfm").rglob("*.py"):
        rel = path.relative_to(ROOT / "nrsfm")
        if rel.parts[0] in top:
            continue
        if re.search(r"^\s*(import data_tools|from data_tools\b)", path.read_text(), re.M):
            offenders.append(str(rel))
    assert offenders == []


def test_run_with_the_admm_shape_solver(tmp_path, good, seq):
    out = tmp_path / "admm.npz"
    assert (
        main(
            [
                "run",
                str(good),
                "-o",
                str(out),
                "--shape-solver",
                "admm",
                "--given-rotations",
                "--quiet",
            ]
        )
        == 0
    )
    with np.load(out) as z:
        assert z["shapes"].shape == seq.shapes.shape
        assert "shape_rho" in z.files  # the ADMM's penalty schedule ran
        assert float(z["e3d"]) < 0.1  # noise-free, true cameras


def test_benchmark_checks_its_folders_before_any_work(tmp_path, monkeypatch, capsys):
    """No data folder, a data folder that is not one and an output that cannot be written
    are command-line errors (exit 2, one line, as for mocap), before any task runs."""
    monkeypatch.delenv("NRSFM_DATA", raising=False)
    cases = [
        (["--out", tmp_path / "a"], "no data folder: pass --data DIR or set NRSFM_DATA"),
        (["--data", tmp_path / "none", "--out", tmp_path / "b"], "is not a folder"),
        (["--sequences", "synthetic-1", "--out", "/proc/nrsfm-out"], "--out /proc/nrsfm-out"),
    ]
    for args, message in cases:
        with pytest.raises(SystemExit) as exit_:
            main(["benchmark", *map(str, args), "--only", "mocap", "--quick", "--quiet"])
        assert exit_.value.code == 2 and message in capsys.readouterr().err
    assert not (tmp_path / "a" / "cache").exists() and not (tmp_path / "b").exists()


@pytest.mark.parametrize("frames", ["0", "1"])
def test_demo_video_frames_is_a_command_line_error_below_two(frames, capsys):
    with pytest.raises(SystemExit) as exit_:
        main(["demo", "--video", "--frames", frames])
    assert exit_.value.code == 2
    assert f"argument --frames: must be at least 2; got {frames}" in capsys.readouterr().err

"""Benchmark tasks, local processes, resumable cache, plan, report, CLI."""

import json

import numpy as np
import pytest

import data_tools as dt
from nrsfm.experiments import (
    Task,
    build_plan,
    load_sequence,
    run_task,
    run_tasks,
    runner,
    unique_tasks,
)

SEQS = ["synthetic-1", "synthetic-2"]


def _tiny_tasks():
    ts = [
        Task.make("mocap", sequence=s, method=m, K=2, seed=0, data=None)
        for s in SEQS
        for m in ("organic", "bmm")
    ]
    ts += [
        Task.make(
            "noise", sequence="synthetic-1", method="organic", sigma=0.05, run=r, seed=0, data=None
        )
        for r in range(2)
    ]
    ts += [
        Task.make(
            "missing",
            sequence="synthetic-3-40-24-2",
            method="organic",
            pattern="uniform",
            fraction=0.2,
            seed=0,
            data=None,
        )
    ]
    return ts


def _strip_times(rows):
    return [{k: v for k, v in r.items() if not k.startswith("t_")} for r in rows]


def test_task_key_is_stable_and_parameter_dependent():
    a = Task.make("mocap", sequence="pickup", method="bmm", K=12)
    b = Task.make("mocap", K=12, method="bmm", sequence="pickup")
    c = Task.make("mocap", sequence="pickup", method="bmm", K=11)
    assert a == b and a.key == b.key and a.key != c.key
    assert a.key.startswith("mocap-")
    with pytest.raises(ValueError, match="unknown experiment"):
        Task.make("nope", sequence="pickup")


def test_load_sequence_synthetic_names():
    s = load_sequence("synthetic-3-40-24-2")
    assert (s.n_frames, s.n_points, s.K) == (40, 24, 2)
    assert load_sequence("synthetic-5").W.shape == (60, 15)
    with pytest.raises(ValueError, match="synthetic-SEED"):
        load_sequence("synthetic-1-2-3-4-5")


def test_local_processes_match_in_process(tmp_path):
    tasks = _tiny_tasks()
    serial = run_tasks(tasks, cache_dir=None, workers=1)
    pooled = run_tasks(tasks, cache_dir=tmp_path / "c", workers=2)
    assert _strip_times(serial) == _strip_times(pooled)
    assert len(list((tmp_path / "c").glob("*.json"))) == len(tasks)
    assert not list((tmp_path / "c").glob("*.tmp"))


def test_interrupted_sweep_resumes_without_redoing(tmp_path, monkeypatch):
    tasks = _tiny_tasks()
    calls = []
    real = runner.run_task

    def counting(task):
        calls.append(task.key)
        return real(task)

    monkeypatch.setattr(runner, "run_task", counting)

    class Stop(Exception):
        pass

    def interrupt(task, rows, cached):
        if len(calls) == 3:
            raise Stop  # as if killed after 3 tasks

    with pytest.raises(Stop):
        run_tasks(tasks, cache_dir=tmp_path, workers=1, progress=interrupt)
    assert len(calls) == 3 and len(list(tmp_path.glob("*.json"))) == 3
    calls.clear()
    seen = []
    rows = run_tasks(
        tasks, cache_dir=tmp_path, workers=1, progress=lambda t, r, cached: seen.append(cached)
    )
    assert len(calls) == len(tasks) - 3  # only the unfinished ones
    assert seen.count(True) == 3
    assert _strip_times(rows) == _strip_times(run_tasks(tasks, workers=1))


def test_corrupt_or_foreign_cache_file_is_rerun(tmp_path):
    t = _tiny_tasks()[0]
    (tmp_path / f"{t.key}.json").write_text("{not json")
    assert runner.load_cached(t, tmp_path) is None
    other = _tiny_tasks()[1]
    (tmp_path / f"{t.key}.json").write_text(
        json.dumps(dict(experiment=other.experiment, params=other.params_json, rows=[]))
    )
    assert runner.load_cached(t, tmp_path) is None
    run_tasks([t], cache_dir=tmp_path)
    assert runner.load_cached(t, tmp_path)[0]["sequence"] == "synthetic-1"


def test_run_tasks_rejects_bad_arguments():
    with pytest.raises(ValueError, match="workers"):
        run_tasks([], workers=0)
    t = _tiny_tasks()[0]
    with pytest.raises(ValueError, match="duplicate"):
        run_tasks([t, t])


def test_plan_covers_every_experiment():
    plan = build_plan(sequences=["synthetic-1"], quick=True)
    assert set(plan) == {
        "mocap",
        "pseudo_inverse",
        "rotation_ablation",
        "noise",
        "missing",
        "n_ablation",
        "k_sweep",
        "shape",
        "perspective",
    }
    tasks = unique_tasks(plan)
    assert len({t.key for t in tasks}) == len(tasks)
    full = build_plan(sequences=["synthetic-1"], only=["noise"])
    assert len(full["noise"]) == 6 * 4 * 10  # sigmas x methods x runs
    with pytest.raises(ValueError, match="unknown experiment"):
        build_plan(only=["tables"], sequences=["synthetic-1"])


def test_shape_table_rows_cells_and_ratio():
    """The shape experiment: its rows (without MoCap data: the synthetic ones), one task per
    row and formulation, a cell that runs without data, and the table's best and ratio."""
    from nrsfm.experiments.shape import COLUMNS, run_shape, shape_rows, shape_table

    plan = build_plan(only=["shape"], quick=True, external="/nonexistent")
    assert len(plan["shape"]) == 2 * len(COLUMNS)  # rank-deficient, exact
    assert len(shape_rows()) == 4 + 8 + 2 + 24  # without the back row
    row = dict(kind="exact", K=2, scale=1e3)
    (cell,) = run_shape(row, "default")
    assert cell["row"] == "exact rank K = 2" and cell["e3d"] < 1e-8
    vals = [0.02, 0.01] + [0.04] * (len(COLUMNS) - 2)  # default, then the others
    rows = [
        dict(row="a", kind="mocap", column=c, e3d=e, t_shape=1.0) for c, e in zip(COLUMNS, vals)
    ]
    rows += [dict(row="b", kind="noise", column="default", e3d=e, t_shape=1.0) for e in (0.1, 0.3)]
    columns, lines, _ = shape_table(rows)
    assert columns[-2:] == ["best", "default / best"]
    assert lines[0][1:] == vals + [0.01, 2.0]
    assert lines[1][1] == pytest.approx(0.2)
    assert lines[1][2:] == [None] * (len(COLUMNS) + 1)  # cells no task filled: no best


def _rigid_motion(F=20, P=12, seed=0):
    """(F, 3, P) shapes of one rigid body turning and moving (QR of random matrices)."""
    rng = np.random.default_rng(seed)
    body = rng.standard_normal((3, P))
    Q = np.linalg.qr(rng.standard_normal((F, 3, 3)))[0]
    Q *= np.sign(np.linalg.det(Q))[:, None, None]  # proper rotations
    return Q @ body + rng.standard_normal((F, 3, 1))


def test_rigid_neighbour_fill_is_exact_on_a_rigid_body():
    """A lost point of a rigid body is where its neighbours carry it; the fill leaves seen
    entries alone and refuses a bad k."""
    from nrsfm.experiments.fill import rigid_neighbour_fill

    X = _rigid_motion()
    observed = np.ones((20, 12), bool)
    observed[8:, 3] = False  # lost to the end
    observed[:5, 7] = False  # starts late
    observed[10:14, [0, 1, 2]] = False  # a block of three
    wrong = np.where(observed[:, None, :], X, 100.0)  # what the fill must replace
    filled = rigid_neighbour_fill(wrong, observed, k=4)
    np.testing.assert_allclose(filled, X, atol=1e-9)
    deformed = wrong.copy()
    deformed[:, :, 5] += 1.0  # a neighbour that slides
    assert np.abs(rigid_neighbour_fill(deformed, observed)[8:, :, 3] - X[8:, :, 3]).max() > 0.1
    with pytest.raises(ValueError, match="k must be at least 1"):
        rigid_neighbour_fill(X, observed, k=0)
    with pytest.raises(ValueError, match="observed must have shape"):
        rigid_neighbour_fill(X, observed[1:])


def test_point_errors_and_seen_e3d_agree_with_e3d():
    """A frame's e3d is the RMS of its points' errors (RMS radius 1); e3d on the seen points
    is e3d when all are seen, and ignores what happens to the unseen ones."""
    import nrsfm
    from nrsfm.experiments.fill import e3d_seen, lost_point_means, point_errors

    rng = np.random.default_rng(1)
    gt = rng.standard_normal((6, 3, 10))
    est = 2.0 * gt + 0.1 * rng.standard_normal(gt.shape)
    err = point_errors(est, gt)
    np.testing.assert_allclose(
        np.sqrt(np.mean(err**2, axis=1)), nrsfm.e3d(est, gt, per_frame=True), rtol=1e-12
    )
    observed = np.ones((6, 10), bool)
    assert e3d_seen(est, gt, observed) == pytest.approx(nrsfm.e3d(est, gt), rel=1e-12)
    observed[2:, 4] = False
    moved = est.copy()
    moved[2:, :, 4] += 50.0
    assert e3d_seen(moved, gt, observed) == pytest.approx(e3d_seen(est, gt, observed))
    assert e3d_seen(moved, gt, observed) < 0.1 < nrsfm.e3d(moved, gt)
    means = lost_point_means(err, observed)
    assert np.isnan(means[0]) and means[4] == pytest.approx(err[2:, 4].mean())


def test_missing_tracks_plan_runs_and_table():
    """The lost-tracks tasks of the missing experiment: one per sequence and pattern (the
    quick set: one), a bad pattern named, a row with the table's fields."""
    from nrsfm.experiments.missing_tracks import COLUMNS, missing_track_table

    quick = [
        t
        for t in build_plan(only=["missing"], sequences=["synthetic-1"], quick=True)["missing"]
        if t.experiment == "missing_tracks"
    ]
    assert [t.params["pattern"] for t in quick] == ["lost"]
    full = build_plan(only=["missing"], sequences=["drink", "pickup", "dance"])["missing"]
    cells = {
        (t.params["sequence"], t.params["pattern"])
        for t in full
        if t.experiment == "missing_tracks"
    }
    assert cells == {
        (n, p) for n in ("drink", "pickup") for p in ("uniform", "lost", "late", "block")
    }
    with pytest.raises(ValueError, match="missing pattern must be one of"):
        build_plan(
            only=["missing"],
            sequences=["synthetic-1"],
            overrides={"track_patterns": ("lost-to-the-end",)},
        )
    task = Task.make(
        "missing_tracks",
        sequence="synthetic-3-40-24-2",
        pattern="late",
        fraction=0.3,
        drop_seed=1,
        seed=0,
        data=None,
    )  # converges: no warning
    (row,) = run_task(task)
    assert len(row["lost"]) == 7 and set(row["flagged"]) <= set(row["lost"])
    assert len(row["point_fill"]) == len(row["point_fill_rigid"]) == 7
    assert row["e3d_seen_complete"] < 1e-6 < row["e3d"]
    columns, (line,), note = missing_track_table([row])
    assert columns == COLUMNS and len(line) == len(COLUMNS) and "seed=1" in note
    assert line[:3] == ["synthetic-3-40-24-2", "late", row["missing"]]
    fake = dict(
        row,
        lost=[2, 5, 9],
        flagged=[5, 9],
        point_fill=[0.01, 0.3, 0.12],
        point_fill_rigid=[0.02, 0.04, 0.2],
    )
    (line,) = missing_track_table([fake])[1]
    assert [line[i] for i in (11, 13, 16)] == ["0.12-0.30", "0.01-0.01", "0.02-0.20"]


CAP_WARNING = "W-completion-cap"  # the id (docs/warnings.md); no colon: a filter field


# known: the missing-data tasks on synthetic-1 (F = 30, P = 15; 30% and 50%
# missing) stop at the completion's iteration cap; the CLI prints each warning as one line
@pytest.mark.filterwarnings(f"always:{CAP_WARNING}:RuntimeWarning")
def test_benchmark_command_writes_tables_and_plots(tmp_path, capsys):
    from nrsfm.cli import main

    out = tmp_path / "bench"
    argv = ["benchmark", "--out", str(out), "--sequences", "synthetic-1", "--quick"]
    argv += ["--only", "mocap", "missing", "--quiet"]
    rc = main(argv)
    assert rc == 0
    err = capsys.readouterr().err.splitlines()
    assert all(line.startswith(f"nrsfm: warning: {CAP_WARNING}") for line in err), err
    for name in (
        "mocap.md",
        "mocap.csv",
        "missing.md",
        "missing_curve.png",
        "missing_tracks.md",
        "README.md",
    ):
        assert (out / name).is_file(), name
    text = (out / "mocap.md").read_text()
    assert "| synthetic-1 | 2 | organic |" in text
    n_cache = len(list((out / "cache").glob("*.json")))
    assert main(argv) == 0  # again: every task from the cache
    assert len(list((out / "cache").glob("*.json"))) == n_cache
    assert f"({n_cache} from the cache)" in (out / "README.md").read_text()


def test_benchmark_sequences_leave_out_tasks_without_one():
    """The shape experiment's tasks name no sequence: the default run (no --sequences) lists
    the sequences of the other tasks only (a None among them crashed the MoCap table)."""
    from nrsfm.experiments.plan import build_plan, unique_tasks
    from nrsfm.experiments.runner import sequences_of

    tasks = unique_tasks(
        build_plan(
            only=["pseudo_inverse", "shape"],
            quick=True,
            data="/nonexistent",
            external="/nonexistent",
        )
    )
    assert any("sequence" not in t.params for t in tasks)
    assert sequences_of(tasks) == list(dt.MOCAP_NAMES)


def test_perspective_row_and_table():
    from nrsfm.experiments.perspective import perspective_table, run_perspective

    row = dict(kind="synthetic", distance=3, F=30, K=1, motion="smooth", noise=0.0)
    (r,) = run_perspective(row)
    assert r["e3d"] < 1e-8 < 0.02 < r["e3d_orthographic"] and r["perspective_warned"] == ""
    assert r["units_move"] < 1e-6 and r["perturbation_move"] < 1e-5
    columns, lines, note = perspective_table([r])
    assert len(lines) == 1 and len(lines[0]) == len(columns) and "noise-free" in note

"""The perspective table: the orthographic pipeline and the perspective refinement
(``reconstruct(..., intrinsics=)``) side by side on pinhole-camera data (why the refinement
is built so: docs/studies/perspective.md).

Rows (:func:`perspective_rows`): synthetic sequences seen by a pinhole camera
(:class:`data_tools.PerspectiveCamera`) at 2-5 object radii, noise-free and with 1 % image
noise, and at 50 radii (close to orthographic); the real sets' image tracks with their
intrinsics (``kinect_paper``, ``hulk``, ``tshirt``, from the external folder). Each row: e3d
of both, their ratio, seconds of both (one BLAS thread), and how far e3d moves when W and
the intrinsics are scaled together by 0.7 / 3 and when W is perturbed by 1e-7 of its RMS.
"""

from __future__ import annotations

import time

import numpy as np

TITLE = "Perspective refinement: e3d of the orthographic pipeline and of the refinement"

#: the real sets with image tracks and intrinsics
REAL_SETS = ("kinect_paper", "hulk", "tshirt")


def perspective_rows(quick=False, external=None):
    """The table's rows as task parameters (dicts of JSON values): a few when ``quick``; the
    real sets when ``external`` (a folder) is given."""
    if quick:
        rows = [
            dict(kind="synthetic", distance=3, F=60, K=2, motion="smooth", noise=0.0),
            dict(kind="synthetic", distance=3, F=60, K=2, motion="random", noise=0.01),
            dict(kind="synthetic", distance=50, F=60, K=2, motion="smooth", noise=0.01),
        ]
    else:
        rows = [
            dict(kind="synthetic", distance=d, F=F, K=K, motion=m, noise=0.0)
            for d in (2, 3, 5)
            for F in (30, 100, 200)
            for K in (1, 2, 3)
            for m in ("smooth", "random")
        ]
        rows += [
            dict(kind="synthetic", distance=d, F=100, K=K, motion=m, noise=n)
            for d, n in ((2, 0.01), (3, 0.01), (5, 0.01), (50, 0.0), (50, 0.01))
            for K in (1, 2, 3)
            for m in ("smooth", "random")
        ]
    if external is not None:
        Ks = (2,) if quick else (1, 2, 3)
        rows += [
            dict(kind="real", sequence=n, K=K, external=external) for n in REAL_SETS for K in Ks
        ]
    return rows


def find_real(folder=None):
    """The external data folder if it holds the real sets' image tracks, else None."""
    from data_tools.external import external_file

    try:
        return str(external_file(REAL_SETS[0], folder).parent.parent)
    except (FileNotFoundError, ValueError):
        return None


def row_label(row):
    if row["kind"] == "real":
        return f"{row['sequence']}, K = {row['K']}"
    noise = f"{100 * row['noise']:g} % noise" if row["noise"] else "noise-free"
    return f"{row['distance']} radii, F = {row['F']}, K = {row['K']}, {row['motion']}, {noise}"


def _data(row):
    """(pixel tracks (2F, P), intrinsics (3, 3), ground-truth camera-frame shapes, K)."""
    import data_tools as dt

    if row["kind"] == "real":
        s = dt.load_external(row["sequence"], row["external"])
        tr = s.extra["image_tracks"]
        return tr.reshape(2 * tr.shape[0], -1), s.extra["intrinsics"], s.shapes, int(row["K"])
    cam = dt.PerspectiveCamera(distance=float(row["distance"]))
    K, F = int(row["K"]), int(row["F"])
    s = dt.make_synthetic(
        F=F, P=60, K=K, motion=row["motion"], noise=row["noise"], seed=0, camera=cam
    )
    return s.W, s.extra["intrinsics"], s.shapes, K


def run_perspective(row, seed=0, data=None):
    """One row: both pipelines on the row's data; e3d, seconds, the one-answer moves."""
    import warnings

    import nrsfm
    from nrsfm.stages.perspective import normalise
    from nrsfm.warnings_catalog import ids_in

    W, A, truth, K = _data(row)
    with warnings.catch_warnings():  # the orthographic pipeline on pinhole data may warn
        warnings.simplefilter("ignore")
        t0 = time.perf_counter()
        ortho = nrsfm.reconstruct(normalise(W, A).reshape(W.shape), K, seed=seed)
    with warnings.catch_warnings(record=True) as caught:  # the refinement's own warnings
        warnings.simplefilter("always")
        t1 = time.perf_counter()
        res = nrsfm.reconstruct(W, K, intrinsics=A, seed=seed)
        t2 = time.perf_counter()
    warned = "; ".join(sorted({i for w in caught for i in ids_in(w.message)}))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        scaled = nrsfm.reconstruct(W * 0.7 / 3, K, intrinsics=A * [[0.7 / 3], [0.7 / 3], [1]])
        bump = 1e-7 * np.sqrt(np.mean(W**2)) * np.random.default_rng(1).standard_normal(W.shape)
        perturbed = nrsfm.reconstruct(W + bump, K, intrinsics=A, seed=seed)
    e = float(nrsfm.e3d(res.shapes, truth))
    moved = [abs(float(nrsfm.e3d(r.shapes, truth)) - e) for r in (scaled, perturbed)]
    p = res.perspective
    out = dict(row=row_label(row), kind=row["kind"], K=K, distance=row.get("distance"))
    out.update(noise=row.get("noise"), e3d_orthographic=float(nrsfm.e3d(ortho.shapes, truth)))
    out.update(e3d=e, start=p.start, iterations=int(p.n_iter), units_move=moved[0])
    out.update(perturbation_move=moved[1], t_orthographic=t1 - t0, t_perspective=t2 - t1)
    out.update(t_refinement=float(res.timings["perspective"]), perspective_warned=warned)
    return [out]


def perspective_table(rows):
    """(columns, lines, note) of the rows, in plan order, and the acceptance figures."""
    lines = []
    for r in rows:
        ratio = r["e3d"] / r["e3d_orthographic"] if r["e3d_orthographic"] else None
        t_ratio = r["t_perspective"] / r["t_orthographic"]
        line = [r["row"], r["e3d_orthographic"], r["e3d"], ratio, r["start"], r["iterations"]]
        line += [_moved(r), r["t_orthographic"], r["t_perspective"], t_ratio]
        lines.append(line + [r["perspective_warned"] or "-"])
    note = _summary(rows)
    columns = [
        "data",
        "orthographic e3d",
        "perspective e3d",
        "ratio",
        "start",
        "iterations",
        "e3d move (units, 1e-7)",
        "s orthographic",
        "s perspective",
        "time ratio",
        "warned",
    ]
    return columns, lines, note


def _moved(row):
    """The larger e3d move under the two changes: relative (a fraction of e3d), or absolute
    where e3d is at most 1e-4 (exact data, where a relative move means nothing)."""
    move = max(row["units_move"], row["perturbation_move"])
    return move if row["e3d"] <= EXACT else move / row["e3d"]


#: e3d at most this counts as exact (the moves are then absolute)
EXACT = 1e-4


def _summary(rows):
    """The figures the refinement is judged by, from the rows there are."""
    parts = []
    exact = [r for r in rows if r["kind"] == "synthetic" and not r["noise"] and r["distance"] <= 5]
    if exact:
        parts.append(
            f"noise-free at 2-5 radii: largest perspective e3d {max(r['e3d'] for r in exact):.2e} "
            f"(of {len(exact)}; orthographic {min(r['e3d_orthographic'] for r in exact):.4f}-"
            f"{max(r['e3d_orthographic'] for r in exact):.4f})"
        )
    noisy = [r for r in rows if r["kind"] == "synthetic" and r["noise"] and r["distance"] <= 5]
    if noisy:
        worst = max(r["e3d"] / r["e3d_orthographic"] for r in noisy)
        parts.append(f"1 % noise at 2-5 radii: largest ratio {worst:.3f} (of {len(noisy)})")
    far = [r for r in rows if r["kind"] == "synthetic" and r["distance"] >= 50]
    if far:
        worst = max(r["e3d"] / r["e3d_orthographic"] for r in far)
        parts.append(f"50 radii: largest ratio {worst:.3f}")
    real = [r for r in rows if r["kind"] == "real" and r["K"] == 2]
    if real:
        gm = float(np.exp(np.mean([np.log(r["e3d"] / r["e3d_orthographic"]) for r in real])))
        slow = max(r["t_perspective"] for r in real)
        parts.append(f"real sets at K = 2: geometric mean ratio {gm:.3f}, at most {slow:.2f} s")
    rel = [_moved(r) for r in rows if r["e3d"] > EXACT]
    ab = [_moved(r) for r in rows if r["e3d"] <= EXACT]
    if rel:
        parts.append(
            f"e3d moves by at most {100 * max(rel):.3f} % under W x 0.7/3 or a 1e-7 "
            "perturbation" + (f" (exact rows: at most {max(ab):.1e})" if ab else "")
        )
    return (
        "e3d against the camera-frame ground truth (per-frame similarity alignment); the "
        "orthographic pipeline runs on the tracks normalised by the intrinsics; e3d move: "
        f"the larger change of e3d when W and the intrinsics are scaled by 0.7/3 or W is "
        f"perturbed by 1e-7 of its RMS, as a fraction of e3d (absolute where e3d <= {EXACT:g}); "
        "seconds of one reconstruct, one BLAS thread. " + "; ".join(parts) + "."
    )

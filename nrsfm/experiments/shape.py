"""The shape-stage table: the shape stage alone, on ground-truth rotations, per formulation,
on every kind of data the default has to serve (why this default: docs/studies/shape.md).

Rows (:func:`shape_rows`): the Akhter sequences, clean and noisy; a rigid body plus a planar
deformation; exactly rank-K shapes at three scales of W; ``back`` re-projected by a camera
turning at random. Columns (:data:`COLUMNS`): the default and three other formulations, the
best of those three and the default's e3d as a multiple of it.
"""

from __future__ import annotations

import time

import numpy as np

TITLE = "Shape stage: e3d per formulation"


def _bilinear(**fields):
    from nrsfm import BilinearSettings

    return BilinearSettings(**fields)


def _admm():
    from nrsfm import AdmmSettings

    return AdmmSettings()


#: column -> the shape settings of that formulation, as a function of K
COLUMNS = {
    "default": lambda K: _bilinear(),
    "rank K, mu_factor .03": lambda K: _bilinear(rank=K, mu_factor=0.03, mu_noise=0.0),
    "admm": lambda K: _admm(),
    "rank 3K, mu_factor .01": lambda K: _bilinear(rank=3 * K, mu_factor=0.01, mu_noise=0.0),
}


def shape_rows(quick=False, external=None, mocap=True):
    """The table's rows as task parameters (dicts of JSON values): one of each kind when
    ``quick``; without the MoCap rows unless ``mocap``; the ``back`` row when ``external``
    (a folder) is given."""
    if quick:
        rows = [
            dict(kind="mocap", sequence="pickup"),
            dict(kind="noise", sequence="pickup", sigma=0.10, noise_seed=0),
            dict(kind="deficient", K=2),
            dict(kind="exact", K=3, scale=1e3),
        ]
    else:
        rows = [dict(kind="mocap", sequence=n) for n in ("drink", "pickup", "yoga", "stretch")]
        rows += [
            dict(kind="noise", sequence=n, sigma=s, noise_seed=r)
            for n in ("pickup", "stretch")
            for s in (0.05, 0.10)
            for r in (0, 1)
        ]
        rows += [dict(kind="deficient", K=K) for K in (2, 3)]
        rows += [dict(kind="exact", K=K, scale=c) for K in range(1, 9) for c in (1e-3, 1.0, 1e3)]
    if not mocap:
        rows = [r for r in rows if r["kind"] not in ("mocap", "noise")]
    if external is not None:
        rows.append(dict(kind="external", sequence="back", path="random", external=external))
    return rows


def find_external(folder=None):
    """The external data folder if it holds ``back``, else None."""
    from data_tools.external import external_file

    try:
        return str(external_file("back", folder).parent.parent)
    except (FileNotFoundError, ValueError):
        return None


def row_label(row):
    """The table row a task belongs to (the noise seeds and the scales share one)."""
    return {
        "mocap": "{sequence}",
        "noise": "{sequence} sigma {sigma:.2f}",
        "deficient": "rigid + planar, K = {K}",
        "exact": "exact rank K = {K}",
        "external": "{sequence}, camera path {path}",
    }[row["kind"]].format(**row)


def _row_sequence(row, data):
    """(Sequence, the factor W is multiplied by) of a row."""
    import dataclasses

    import data_tools as dt

    kind = row["kind"]
    if kind == "mocap":
        return dt.load_mocap(row["sequence"], data), 1.0
    if kind == "noise":
        seq = dt.load_mocap(row["sequence"], data)
        W = dt.add_noise(seq.W, row["sigma"], seed=row["noise_seed"])
        return dataclasses.replace(seq, W=W), 1.0
    if kind == "deficient":
        return dataclasses.replace(dt.make_rank_deficient(seed=0), K=int(row["K"])), 1.0
    if kind == "exact":
        K = row["K"]
        return dt.make_synthetic(F=40, P=3 * K + 2, K=K, motion="random", seed=K), row["scale"]
    seq = dt.load_external(row["sequence"], row["external"])
    return dt.reproject(seq, row["path"], 0.0, seed=0), 1.0


def run_shape(row, column, seed=0, data=None):
    """One cell: the shape stage of formulation ``column`` on ``row`` with the ground-truth
    rotations; e3d, seconds and the warnings raised."""
    import warnings

    import nrsfm

    seq, scale = _row_sequence(row, data)
    settings = nrsfm.Settings(shape=COLUMNS[column](seq.K))
    t0 = time.perf_counter()
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        res = nrsfm.reconstruct(
            scale * seq.W, seq.K, rotations=seq.rotations, seed=seed, settings=settings
        )
    seconds = time.perf_counter() - t0
    e3d = float(nrsfm.e3d(res.shapes, scale * seq.shapes))
    cell = dict(row=row_label(row), kind=row["kind"], column=column, K=int(seq.K), e3d=e3d)
    warned = sorted({str(w.message)[:60] for w in caught})
    return [dict(cell, t_shape=float(res.timings["shape"]), t_total=seconds, warned=warned)]


def shape_table(rows):
    """(columns, lines, note): one line per row label (mean over noise seeds, largest over
    scales), one column per formulation, the best of the others and the default / best."""
    cols = list(COLUMNS)
    lines = []
    for label in dict.fromkeys(r["row"] for r in rows):
        kind = next(r["kind"] for r in rows if r["row"] == label)
        cells = []
        for c in cols:
            vals = [r["e3d"] for r in rows if r["row"] == label and r["column"] == c]
            cells.append(
                float(np.max(vals) if kind == "exact" else np.mean(vals)) if vals else None
            )
        have = [v for v in cells[1:] if v is not None]
        best = min(have) if have else None
        ratio = None if best in (None, 0) or cells[0] is None else cells[0] / best
        lines.append([label] + cells + [best, ratio])
    secs = ", ".join(f"{c} {sum(r['t_shape'] for r in rows if r['column'] == c):.1f}" for c in cols)
    note = (
        "e3d of the shape stage alone (ground-truth rotations; noise: mean of the seeds; "
        f"exact: largest over W x 1e-3, 1, 1e3). Shape-stage seconds in all, one BLAS thread: "
        f"{secs}."
    )
    return ["data"] + cols + ["best", "default / best"], lines, note

"""The shape-stage table: the shape stage alone, on ground-truth rotations, for
each formulation, on every kind of data the default has to serve.

Rows (:func:`shape_rows`):

* the four Akhter sequences as they are (drink, pickup, yoga, stretch);
* pickup and stretch with Gaussian noise of std sigma x the mean row std of W
  (:func:`data_tools.add_noise`), sigma .05 and .10, two noise seeds (the table shows
  their mean);
* a rank-deficient shape: a rigid body plus a planar deformation
  (:func:`data_tools.make_rank_deficient`, W of rank 5), at the true K = 2 and at K = 3;
* noise-free exactly rank-K shapes, K = 1..8, at the scales 1e-3, 1 and 1e3 of W (the
  table shows the largest e3d over the scales);
* when the external data folder is found (``--external-data``, ``NRSFM_EXTERNAL_DATA``, or
  ``external/`` beside ``mocap/``): ``back`` re-projected by a camera that turns at random
  every frame (:func:`data_tools.reproject`, path ``random``).

Columns (:data:`COLUMNS`): the default shape stage and three other formulations: the
bilinear solver at rank K with ``mu_factor = 0.03``, the paper's ADMM, the bilinear solver
at rank 3K with ``mu_factor = 0.01`` (both bilinear columns with a constant factor,
``mu_noise = 0``). The last columns are the best of the columns other than the default
and the default's e3d as a multiple of that best.
"""

from __future__ import annotations

import time

import numpy as np

__all__ = ["COLUMNS", "TITLE", "run_shape", "shape_rows", "shape_table", "shape_tasks"]

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

_AKHTER = ("drink", "pickup", "yoga", "stretch")
_NOISY = ("pickup", "stretch")
_SIGMAS = (0.05, 0.10)
_SCALES = (1e-3, 1.0, 1e3)


def shape_rows(quick=False, external=None, mocap=True):
    """The rows of the table as task parameters (dicts of JSON values).

    Parameters
    ----------
    quick : bool
        One row of each kind (pickup, pickup at sigma .10 with one seed, the rank-deficient
        shape at K = 2, the exact shape at K = 3 and scale 1e3).
    external : str, optional
        Folder of the external sequences; the ``back`` row is added when it holds ``back``.
    mocap : bool
        Include the MoCap rows (False when no MoCap folder is given).
    """
    if quick:
        rows = [dict(kind="mocap", sequence="pickup"),
                dict(kind="noise", sequence="pickup", sigma=0.10, noise_seed=0),
                dict(kind="deficient", K=2), dict(kind="exact", K=3, scale=1e3)]
    else:
        rows = [dict(kind="mocap", sequence=n) for n in _AKHTER]
        rows += [dict(kind="noise", sequence=n, sigma=s, noise_seed=r)
                 for n in _NOISY for s in _SIGMAS for r in (0, 1)]
        rows += [dict(kind="deficient", K=K) for K in (2, 3)]
        rows += [dict(kind="exact", K=K, scale=c) for K in range(1, 9) for c in _SCALES]
    if not mocap:
        rows = [r for r in rows if r["kind"] not in ("mocap", "noise")]
    if external is not None:
        rows.append(dict(kind="external", sequence="back", path="random", external=external))
    return rows


def shape_tasks(make, quick=False, external=None, mocap=True):
    """The experiment's tasks, ``make("shape", row=..., column=...)`` for every row of
    :func:`shape_rows` and every column."""
    rows = shape_rows(quick, find_external(external), mocap=mocap)
    return [make("shape", row=r, column=c) for r in rows for c in COLUMNS]


def find_external(folder=None):
    """The external data folder if it holds ``back``, else None."""
    from data_tools.external import external_file

    try:
        return str(external_file("back", folder).parent.parent)
    except (FileNotFoundError, ValueError):
        return None


def row_label(row):
    """The table row a task belongs to (the noise seeds and the scales share one)."""
    kind = row["kind"]
    if kind == "mocap":
        return row["sequence"]
    if kind == "noise":
        return f"{row['sequence']} sigma {row['sigma']:.2f}"
    if kind == "deficient":
        return f"rigid + planar, K = {row['K']}"
    if kind == "exact":
        return f"exact rank K = {row['K']}"
    return f"{row['sequence']}, camera path {row['path']}"


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
    """One cell: the shape stage of formulation ``column`` on row ``row``, with the
    ground-truth rotations; e3d and the shape stage's seconds."""
    import warnings

    import nrsfm

    seq, scale = _row_sequence(row, data)
    t0 = time.perf_counter()
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        res = nrsfm.reconstruct(scale * seq.W, seq.K, rotations=seq.rotations, seed=seed,
                                settings=nrsfm.Settings(shape=COLUMNS[column](seq.K)))
    seconds = time.perf_counter() - t0
    return [dict(row=row_label(row), kind=row["kind"], column=column, K=int(seq.K),
                 e3d=float(nrsfm.e3d(res.shapes, scale * seq.shapes)),
                 t_shape=float(res.timings["shape"]), t_total=float(seconds),
                 warned=sorted({str(w.message)[:60] for w in caught}))]


def shape_table(rows):
    """The table as (columns, lines, note): one line per row label (mean over noise seeds,
    largest over scales), one column per formulation, the best of them and the default's
    multiple of it (:mod:`.report` makes it a Table)."""
    labels = list(dict.fromkeys(r["row"] for r in rows))
    cols = list(COLUMNS)
    lines = []
    for label in labels:
        cells = []
        for c in cols:
            vals = [r["e3d"] for r in rows if r["row"] == label and r["column"] == c]
            kind = next(r["kind"] for r in rows if r["row"] == label)
            cells.append(None if not vals else
                         float(np.max(vals) if kind == "exact" else np.mean(vals)))
        have = [v for v in cells[1:] if v is not None]
        best = min(have) if have else None
        ratio = None if best in (None, 0) or cells[0] is None else cells[0] / best
        lines.append([label] + cells + [best, ratio])
    secs = {c: sum(r["t_shape"] for r in rows if r["column"] == c) for c in cols}
    note = ("e3d of the shape stage alone (ground-truth rotations; noise: mean of the "
            "seeds; exact: largest over W x 1e-3, 1, 1e3). Shape-stage seconds in all, one "
            "BLAS thread: " + ", ".join(f"{c} {s:.1f}" for c, s in secs.items()) + ".")
    return ["data"] + cols + ["best", "default / best"], lines, note

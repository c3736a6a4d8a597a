"""Benchmark tasks: one independent, seeded, picklable unit of work each.

A :class:`Task` is an experiment name and its parameters (plain JSON values); running it
(:func:`run_task`) loads its sequence, runs :func:`nrsfm.reconstruct` and returns rows
(dicts of JSON values). A task's result depends on its parameters only (every random choice
is seeded from them, one BLAS thread), so it is the same whichever process or machine runs
it; its :attr:`Task.key` names its cache file.
"""

from __future__ import annotations

import hashlib
import json
import os
import time
from dataclasses import dataclass

import numpy as np

__all__ = ["Task", "load_sequence", "run_task", "RUNNERS", "AKHTER_ROTATIONS"]

#: Sequences whose stored rotations are moving ground-truth cameras (e_R is defined).
AKHTER_ROTATIONS = ("drink", "pickup", "yoga", "stretch")


@dataclass(frozen=True)
class Task:
    """One unit of work: ``experiment`` (a key of :data:`RUNNERS`) and its parameters."""

    experiment: str
    params_json: str

    @classmethod
    def make(cls, experiment, **params):
        if experiment not in RUNNERS:
            raise ValueError(f"unknown experiment {experiment!r}; expected one of "
                             f"{sorted(RUNNERS)}")
        return cls(experiment, json.dumps(params, sort_keys=True))

    @property
    def params(self):
        return json.loads(self.params_json)

    @property
    def key(self):
        """Stable file-name-safe identifier (experiment + hash of the parameters)."""
        digest = hashlib.sha1(self.params_json.encode()).hexdigest()[:16]
        return f"{self.experiment}-{digest}"

    def __str__(self):
        p = self.params
        p.pop("data", None)
        return f"{self.experiment}(" + ", ".join(f"{k}={v}" for k, v in p.items()) + ")"


def load_sequence(name, data=None):
    """A MoCap sequence by name, or a small synthetic one named ``synthetic-SEED``.

    ``synthetic-SEED[-F-P-K]`` (e.g. ``synthetic-3`` or ``synthetic-3-40-20-2``) gives
    :func:`data_tools.make_synthetic` with that seed (default F=30, P=15, K=2).
    """
    import data_tools

    if name.startswith("synthetic-"):
        parts = [int(x) for x in name.split("-")[1:]]
        if not 1 <= len(parts) <= 4:
            raise ValueError(f"synthetic sequence name must be synthetic-SEED[-F-P-K]; "
                             f"got {name!r}")
        seed, F, P, K = (parts + [30, 15, 2][len(parts) - 1:])[:4]
        return data_tools.make_synthetic(F=F, P=P, K=K, seed=seed, name=name)
    return data_tools.load_mocap(name, data)


def _gt_rotations(seq):
    """Ground-truth cameras usable for e_R (moving Akhter cameras, synthetic)."""
    if seq.name in AKHTER_ROTATIONS or seq.name.startswith("synthetic-"):
        return seq.rotations
    return None


def _errors(res, seq, prefix=""):
    out = {}
    if seq.shapes is None:
        return out
    err = res.errors(seq.shapes, _gt_rotations(seq))
    for k, v in err.items():
        out[prefix + k] = float(v)
    return out


def _timed(fn, *args, **kwargs):
    t0 = time.perf_counter()
    out = fn(*args, **kwargs)
    return out, time.perf_counter() - t0


def _reconstruct(W, K, method="organic", shape=None, **kw):
    """``nrsfm.reconstruct`` timed. ``method`` may name a shape solver after a dash
    (``"organic-admm"``: the organic pipeline with the paper's continuation ADMM); ``shape``
    gives the shape solver's settings instead."""
    import nrsfm

    if "-" in method:
        method, kw["shape_solver"] = method.split("-", 1)
    if shape is not None:
        kw["settings"] = nrsfm.Settings(method=method, shape=shape)
        return _timed(nrsfm.reconstruct, W, K, **kw)
    return _timed(nrsfm.reconstruct, W, K, method=method, **kw)


# ----------------------------------------------------------------------------- runners
def run_mocap(sequence, method, K=None, seed=0, data=None):
    """Full pipeline on one sequence: errors and seconds per stage."""
    seq = load_sequence(sequence, data)
    K = seq.K if K is None else int(K)
    res, secs = _reconstruct(seq.W, K, method=method, seed=seed)
    row = dict(sequence=sequence, method=method, K=K, **_errors(res, seq))
    row.update({f"t_{k}": float(v) for k, v in res.timings.items()})
    row["t_total"] = float(secs)
    return [row]


def run_pseudo_inverse(sequence, seed=0, data=None):
    """Table 1: rank-K pseudo-inverse shape, from ground-truth rotations where they exist."""
    seq = load_sequence(sequence, data)
    given = seq.rotations is not None
    res, secs = _reconstruct(seq.W, seq.K, method="pseudo_inverse", seed=seed,
                             rotations=seq.rotations if given else None)
    return [dict(sequence=sequence, K=seq.K,
                 rotations="ground_truth" if given else "estimated",
                 **_errors(res, seq), t_total=float(secs))]


def run_rotation_ablation(sequence, rotations, seed=0, data=None):
    """Table 3: the organic shape stage on rotations from ``bmm``, ``organic`` or GT."""
    seq = load_sequence(sequence, data)
    K = seq.K
    t0 = time.perf_counter()
    if rotations == "ground_truth":
        R = _gt_rotations(seq)
        if R is None:
            return []
    elif rotations == "organic":
        R = None
    else:
        R = _reconstruct(seq.W, K, method=rotations, seed=seed)[0].rotations
    res, _ = _reconstruct(seq.W, K, method="organic", seed=seed, rotations=R)
    return [dict(sequence=sequence, K=K, rotations=rotations, **_errors(res, seq),
                 t_total=float(time.perf_counter() - t0))]


def run_noise(sequence, method, sigma, run, seed=0, data=None):
    """Fig. 3a-b: Gaussian noise of std ``sigma x mean row std of W``, seeded by ``run``."""
    import data_tools

    seq = load_sequence(sequence, data)
    W = data_tools.add_noise(seq.W, sigma, seed=10_000 * seed + run)
    res, secs = _reconstruct(W, seq.K, method=method, seed=seed)
    return [dict(sequence=sequence, method=method, sigma=float(sigma), run=int(run),
                 **_errors(res, seq), t_total=float(secs))]


def run_missing(sequence, method, pattern, fraction, run=0, seed=0, data=None):
    """Fig. 3c: observations removed (``uniform`` or ``tracking``), completed, reconstructed."""
    import data_tools

    seq = load_sequence(sequence, data)
    W, mask = data_tools.drop_tracks(seq.W, fraction, seed=10_000 * seed + run,
                                     pattern=pattern)
    res, secs = _reconstruct(W, seq.K, method=method, seed=seed)
    miss = np.repeat(~mask, 2, axis=0)
    fill = (float(np.linalg.norm((res.W_completed - seq.W)[miss])
                  / np.linalg.norm(seq.W[miss])) if miss.any() else 0.0)
    return [dict(sequence=sequence, method=method, pattern=pattern, fraction=float(fraction),
                 run=int(run), missing=float(1 - mask.mean()), fill_error=fill,
                 **_errors(res, seq), t_completion=float(res.timings.get("completion", 0.0)),
                 t_total=float(secs))]


def run_missing_tracks(sequence, pattern, fraction, drop_seed, seed=0, data=None):
    """The lost-tracks table (issue 24): the organic pipeline on the complete W and on W
    with ``fraction`` of the tracks hit by ``pattern`` (:func:`data_tools.drop_tracks`,
    seeded by ``drop_seed``); the metrics of :func:`.missing_tracks.track_row`."""
    import data_tools

    from .missing_tracks import track_row

    seq = load_sequence(sequence, data)
    W, mask = data_tools.drop_tracks(seq.W, fraction, seed=drop_seed, pattern=pattern)
    complete, _ = _reconstruct(seq.W, seq.K, seed=seed)
    res, secs = _reconstruct(W, seq.K, seed=seed)
    row = dict(sequence=sequence, pattern=pattern, fraction=float(fraction),
               drop_seed=int(drop_seed), K=int(seq.K), missing=float(1 - mask.mean()),
               e3d_complete=_errors(complete, seq)["e3d"], **_errors(res, seq),
               t_total=float(secs))
    row.update(track_row(complete, res, seq.shapes, mask))
    return [row]


def run_n_ablation(sequence, Ns, seed=0, data=None):
    """Fig. 3d: the paper's shape stage (PSVT ADMM) with N = 0..5 on the same (organic)
    rotations; N is that solver's number of unpenalised singular values."""
    from nrsfm import AdmmSettings

    seq = load_sequence(sequence, data)
    base, _ = _reconstruct(seq.W, seq.K, method="organic", seed=seed)
    rows = []
    for N in Ns:
        res, secs = _reconstruct(seq.W, seq.K, method="organic", seed=seed,
                                 rotations=base.rotations, shape=AdmmSettings(N=int(N)))
        rows.append(dict(sequence=sequence, K=seq.K, N=int(N), **_errors(res, seq),
                         t_shape=float(secs)))
    return rows


def run_k_sweep(sequence, K, seed=0, data=None):
    """One K of the K sweep (organic pipeline)."""
    rows = run_mocap(sequence, "organic", K=K, seed=seed, data=data)
    for r in rows:
        r.pop("method")
    return rows


def run_auto_k(sequence, seed=0, data=None):
    """Automatic K (:func:`nrsfm.experiments.autok.choose_K`) and the organic e3d with it."""
    from .autok import choose_K

    seq = load_sequence(sequence, data)
    K, info = choose_K(seq.W)
    res, secs = _reconstruct(seq.W, K, method="organic", seed=seed)
    return [dict(sequence=sequence, K_auto=int(K), K_paper=int(seq.K),
                 rank=int(info["rank"]), **_errors(res, seq), t_total=float(secs))]


def run_shape(row, column, seed=0, data=None):
    """One cell of the shape-stage table (:func:`nrsfm.experiments.shape.run_shape`)."""
    from .shape import run_shape as run

    return run(row, column, seed=seed, data=data)


RUNNERS = {
    "mocap": run_mocap,
    "pseudo_inverse": run_pseudo_inverse,
    "rotation_ablation": run_rotation_ablation,
    "noise": run_noise,
    "missing": run_missing,
    "missing_tracks": run_missing_tracks,
    "n_ablation": run_n_ablation,
    "k_sweep": run_k_sweep,
    "auto_k": run_auto_k,
    "shape": run_shape,
}


def run_task(task):
    """Run one task in this process (one BLAS thread); returns its rows."""
    for var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
        os.environ.setdefault(var, "1")
    from threadpoolctl import threadpool_limits

    with threadpool_limits(limits=1):
        rows = RUNNERS[task.experiment](**task.params)
    return [dict(r, experiment=task.experiment) for r in rows]

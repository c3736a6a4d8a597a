"""Benchmark tasks: one independent, seeded, picklable unit of work each.

A :class:`Task` is an experiment name and its parameters (JSON values); :func:`run_task` runs
it and returns rows (dicts of JSON values). Every random choice is seeded from the parameters
and BLAS runs one thread, so the rows do not depend on the process that runs the task;
:attr:`Task.key` names its cache file.
"""

from __future__ import annotations

import hashlib
import json
import time
from dataclasses import dataclass

import numpy as np

from .missing_tracks import track_row
from .perspective import run_perspective
from .shape import run_shape

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
            raise ValueError(
                f"unknown experiment {experiment!r}; expected one of {sorted(RUNNERS)}"
            )
        return cls(experiment, json.dumps(params, sort_keys=True))

    @property
    def params(self):
        return json.loads(self.params_json)

    @property
    def key(self):
        """File-name-safe identifier: the experiment and a hash of the parameters."""
        return f"{self.experiment}-{hashlib.sha1(self.params_json.encode()).hexdigest()[:16]}"

    def __str__(self):
        p = ", ".join(f"{k}={v}" for k, v in self.params.items() if k != "data")
        return f"{self.experiment}({p})"


def load_sequence(name, data=None):
    """A MoCap sequence by name, or ``synthetic-SEED[-F-P-K]`` (e.g. ``synthetic-3-40-20-2``):
    :func:`data_tools.make_synthetic` with that seed (default F=30, P=15, K=2)."""
    import data_tools

    if not name.startswith("synthetic-"):
        return data_tools.load_mocap(name, data)
    parts = [int(x) for x in name.split("-")[1:]]
    if not 1 <= len(parts) <= 4:
        raise ValueError(f"synthetic sequence name must be synthetic-SEED[-F-P-K]; got {name!r}")
    seed, F, P, K = (parts + [30, 15, 2][len(parts) - 1 :])[:4]
    return data_tools.make_synthetic(F=F, P=P, K=K, seed=seed, name=name)


def _gt_rotations(seq):
    """Ground-truth cameras usable for e_R (moving Akhter cameras, synthetic), else None."""
    if seq.name in AKHTER_ROTATIONS or seq.name.startswith("synthetic-"):
        return seq.rotations
    return None


def _errors(res, seq):
    if seq.shapes is None:
        return {}
    return {k: float(v) for k, v in res.errors(seq.shapes, _gt_rotations(seq)).items()}


def _reconstruct(W, K, method="organic", shape=None, **kw):
    """``nrsfm.reconstruct`` and its seconds. ``"organic-admm"``: the shape solver after the
    dash; ``shape``: the shape solver's settings."""
    import nrsfm

    if "-" in method:
        method, kw["shape_solver"] = method.split("-", 1)
    if shape is not None:
        kw["settings"] = nrsfm.Settings(method=method, shape=shape)
    else:
        kw["method"] = method
    t0 = time.perf_counter()
    res = nrsfm.reconstruct(W, K, **kw)
    return res, time.perf_counter() - t0


def run_mocap(sequence, method, K=None, seed=0, data=None):
    """Full pipeline on one sequence: errors and seconds per stage."""
    seq = load_sequence(sequence, data)
    K = seq.K if K is None else int(K)
    res, secs = _reconstruct(seq.W, K, method=method, seed=seed)
    row = dict(sequence=sequence, method=method, K=K, **_errors(res, seq))
    row.update({f"t_{k}": float(v) for k, v in res.timings.items()})
    return [dict(row, t_total=float(secs))]


def run_pseudo_inverse(sequence, seed=0, data=None):
    """Table 1: rank-K pseudo-inverse shape, from ground-truth rotations where they exist."""
    seq = load_sequence(sequence, data)
    R = seq.rotations
    res, secs = _reconstruct(seq.W, seq.K, method="pseudo_inverse", seed=seed, rotations=R)
    given = "ground_truth" if R is not None else "estimated"
    return [dict(sequence=sequence, K=seq.K, rotations=given, **_errors(res, seq), t_total=secs)]


def run_rotation_ablation(sequence, rotations, seed=0, data=None):
    """Table 6: the organic shape stage on rotations from ``bmm``, ``organic`` or GT."""
    seq = load_sequence(sequence, data)
    t0 = time.perf_counter()
    if rotations == "ground_truth":
        R = _gt_rotations(seq)
        if R is None:
            return []
    elif rotations == "organic":
        R = None
    else:
        R = _reconstruct(seq.W, seq.K, method=rotations, seed=seed)[0].rotations
    res, _ = _reconstruct(seq.W, seq.K, method="organic", seed=seed, rotations=R)
    secs = time.perf_counter() - t0
    return [
        dict(sequence=sequence, K=seq.K, rotations=rotations, **_errors(res, seq), t_total=secs)
    ]


def run_noise(sequence, method, sigma, run, seed=0, data=None):
    """Fig. 4a-b: Gaussian noise of std ``sigma x mean row std of W``, seeded by ``run``."""
    import data_tools

    seq = load_sequence(sequence, data)
    W = data_tools.add_noise(seq.W, sigma, seed=10_000 * seed + run)
    res, secs = _reconstruct(W, seq.K, method=method, seed=seed)
    row = dict(sequence=sequence, method=method, sigma=float(sigma), run=int(run))
    return [dict(row, **_errors(res, seq), t_total=float(secs))]


def run_missing(sequence, method, pattern, fraction, run=0, seed=0, data=None):
    """Fig. 4c: observations removed (``uniform`` or ``tracking``), completed, reconstructed;
    ``fill_error`` = ||W_completed - W|| / ||W|| over the missing entries."""
    import data_tools

    seq = load_sequence(sequence, data)
    W, mask = data_tools.drop_tracks(seq.W, fraction, seed=10_000 * seed + run, pattern=pattern)
    res, secs = _reconstruct(W, seq.K, method=method, seed=seed)
    miss = np.repeat(~mask, 2, axis=0)
    gap = (res.W_completed - seq.W)[miss]
    fill = float(np.linalg.norm(gap) / np.linalg.norm(seq.W[miss])) if miss.any() else 0.0
    row = dict(sequence=sequence, method=method, pattern=pattern, fraction=float(fraction))
    row.update(run=int(run), missing=float(1 - mask.mean()), fill_error=fill, **_errors(res, seq))
    t_completion = float(res.timings.get("completion", 0.0))
    return [dict(row, t_completion=t_completion, t_total=float(secs))]


def run_missing_tracks(sequence, pattern, fraction, drop_seed, seed=0, data=None):
    """The lost-tracks table: the organic pipeline on the complete W and on W with ``fraction``
    of the tracks hit by ``pattern`` (:func:`data_tools.drop_tracks`, seeded by
    ``drop_seed``); the metrics of :func:`.missing_tracks.track_row`."""
    import data_tools

    seq = load_sequence(sequence, data)
    W, mask = data_tools.drop_tracks(seq.W, fraction, seed=drop_seed, pattern=pattern)
    complete, _ = _reconstruct(seq.W, seq.K, seed=seed)
    res, secs = _reconstruct(W, seq.K, seed=seed)
    row = dict(sequence=sequence, pattern=pattern, fraction=float(fraction))
    row.update(drop_seed=int(drop_seed), K=int(seq.K), missing=float(1 - mask.mean()))
    row.update(e3d_complete=_errors(complete, seq)["e3d"], **_errors(res, seq))
    return [dict(row, t_total=float(secs), **track_row(complete, res, seq.shapes, mask))]


def run_n_ablation(sequence, Ns, seed=0, data=None):
    """Fig. 4d: the paper's ADMM shape stage with N = 0..5 (its number of unpenalised
    singular values) on the same organic rotations."""
    from nrsfm import AdmmSettings

    seq = load_sequence(sequence, data)
    R = _reconstruct(seq.W, seq.K, method="organic", seed=seed)[0].rotations
    rows = []
    for N in Ns:
        shape = AdmmSettings(N=int(N))
        res, secs = _reconstruct(seq.W, seq.K, seed=seed, rotations=R, shape=shape)
        rows.append(dict(sequence=sequence, K=seq.K, N=int(N), **_errors(res, seq), t_shape=secs))
    return rows


def run_k_sweep(sequence, K, seed=0, data=None):
    """One K of the K sweep (organic pipeline)."""
    (row,) = run_mocap(sequence, "organic", K=K, seed=seed, data=data)
    del row["method"]
    return [row]


RUNNERS = {
    "mocap": run_mocap,
    "pseudo_inverse": run_pseudo_inverse,
    "rotation_ablation": run_rotation_ablation,
    "noise": run_noise,
    "missing": run_missing,
    "missing_tracks": run_missing_tracks,
    "n_ablation": run_n_ablation,
    "k_sweep": run_k_sweep,
    "shape": run_shape,
    "perspective": run_perspective,
}


def run_task(task):
    """Run one task in this process with one BLAS thread; returns its rows, each with the
    ids of the warnings the task raised (``warned``, ``; ``-separated): a task's outcome
    never depends on the caller's warning filter (a worker forked from a process where
    warnings are errors still finishes)."""
    import warnings

    from threadpoolctl import threadpool_limits

    from ..warnings_catalog import ids_in

    with threadpool_limits(limits=1), warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        rows = RUNNERS[task.experiment](**task.params)
    ids = [ids_in(w.message) or [w.category.__name__] for w in caught]
    warned = "; ".join(sorted({i for group in ids for i in group}))
    return [dict(r, experiment=task.experiment, warned=warned) for r in rows]

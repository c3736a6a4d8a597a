"""Which tasks make up each experiment, for the full and the quick set."""

from __future__ import annotations

from .perspective import find_real, perspective_rows
from .shape import COLUMNS as SHAPE_COLUMNS
from .shape import find_external, shape_rows
from .tasks import AKHTER_ROTATIONS, Task, load_sequence

#: experiment name -> what it regenerates
EXPERIMENTS = {
    "mocap": "MoCap table: organic, bmm, wnn at the paper's K; BMM at Dai's K beside the "
    "peer's run of Dai et al.'s code",
    "pseudo_inverse": "Table 1: rank-K pseudo-inverse shape (ground-truth rotations where "
    "they exist)",
    "rotation_ablation": "Table 6: the organic shape stage on BMM, organic and ground-truth "
    "rotations",
    "noise": "Fig. 4a-b: noise on pickup, e_R and e3d, mean and std over runs",
    "missing": "Fig. 4c: 30% missing (uniform and tracking) on every sequence, and a 10-60% "
    "curve on pickup; the lost-tracks table (e3d of the seen points, fill errors, the flag, "
    "a rigid-neighbour baseline) per pattern",
    "n_ablation": "Fig. 4d: the shape stage's N = 0..5",
    "k_sweep": "e3d as a function of K per sequence",
    "shape": "the shape stage alone on ground-truth rotations, per formulation: clean and "
    "noisy MoCap, rank-deficient and exactly rank-K shapes, back with a moving camera",
    "perspective": "the orthographic pipeline and the perspective refinement on pinhole-camera "
    "data: synthetic at 2-50 object radii, noise-free and noisy; the real sets' image tracks",
}

_FULL = dict(
    methods=("organic", "organic-admm", "bmm", "wnn"),
    noise_sigmas=(0.01, 0.05, 0.1, 0.15, 0.2, 0.25),
    noise_runs=10,
    noise_methods=("organic", "organic-admm", "bmm", "wnn"),
    noise_sequence="pickup",
    missing_methods=("organic", "bmm"),
    missing_patterns=("uniform", "tracking"),
    missing_fraction=0.3,
    missing_sequences=None,
    curve_fractions=(0.1, 0.2, 0.3, 0.4, 0.5, 0.6),
    curve_methods=("organic", "bmm"),
    track_patterns=("uniform", "lost", "late", "block"),
    track_fraction=0.3,
    track_seed=31,
    track_sequences=AKHTER_ROTATIONS,
    Ns=(0, 1, 2, 3, 4, 5),
    ablation_sequences=None,
    k_grid=(1, 2, 3, 4, 5, 6, 8, 10, 12, 14),
    k_span=None,
    sweep_sequences=None,
)
_QUICK = dict(
    _FULL,
    methods=("organic", "bmm"),
    noise_methods=("organic", "bmm", "wnn"),
    noise_sigmas=(0.01, 0.1, 0.25),
    noise_runs=2,
    missing_sequences=("pickup",),
    curve_fractions=(0.1, 0.3, 0.5),
    curve_methods=("organic",),
    track_patterns=("lost",),
    track_sequences=("pickup",),
    ablation_sequences=("pickup",),
    k_span=(-4, -2, 0),
    sweep_sequences=("pickup",),
)


def paper_K(name):
    import data_tools

    return data_tools.MOCAP_K.get(name) or load_sequence(name).K


def _checked(only, sequences, quick, overrides):
    """(experiments, sequences, settings) of :func:`build_plan`, checked."""
    import data_tools

    only = list(only or EXPERIMENTS)
    bad = [e for e in only if e not in EXPERIMENTS]
    if bad:
        raise ValueError(f"unknown experiment(s) {bad}; expected some of {list(EXPERIMENTS)}")
    seqs = list(sequences or data_tools.MOCAP_NAMES)
    s = dict(_QUICK if quick else _FULL)
    bad = sorted(set(overrides or {}) - set(s))
    if bad:
        raise ValueError(f"unknown setting(s) {bad}; expected some of {sorted(s)}")
    s.update(overrides or {})
    return only, seqs, s


def build_plan(
    only=None, sequences=None, quick=False, data=None, seed=0, overrides=None, external=None
):
    """Tasks of the experiments ``only`` (default all), in a stable order: a dict experiment
    -> list of Task, where a task needed by several experiments appears under each.

    ``sequences`` default to the 8 MoCap sequences (noise and curve: pickup when among them,
    else the first); ``quick``: the quick set of :data:`_QUICK`; ``data``: the MoCap folder
    passed to every task; ``overrides``: settings of :data:`_FULL` replaced, e.g.
    ``{"missing_patterns": ("uniform",)}``; ``external``: the folder of the external
    sequences (the shape table's ``back`` row; default :func:`.shape.find_external`).
    ValueError for an unknown experiment, setting or missing-data pattern.
    """
    import data_tools
    from data_tools.noise import PATTERNS

    from ..validation import check_choice

    only, seqs, s = _checked(only, sequences, quick, overrides)
    data = None if data is None else str(data)
    one = s["noise_sequence"] if s["noise_sequence"] in seqs else seqs[0]

    def mk(exp, **p):
        return Task.make(exp, **p, seed=seed, data=data)

    def mocap(name, method, K=None):
        return mk("mocap", sequence=name, method=method, K=int(K or paper_K(name)))

    def subset(key):
        return [n for n in seqs if s[key] is None or n in s[key]] or [one]

    plan = {}
    if "mocap" in only:
        plan["mocap"] = [mocap(n, m) for n in seqs for m in s["methods"]]
        plan["mocap"] += [mocap(n, "bmm", data_tools.DAI_K.get(n, paper_K(n))) for n in seqs]
    if "pseudo_inverse" in only:
        plan["pseudo_inverse"] = [mk("pseudo_inverse", sequence=n) for n in seqs]
    if "rotation_ablation" in only:
        ts = []
        for n in subset("ablation_sequences"):
            gt = n in AKHTER_ROTATIONS or n.startswith("synthetic-")
            ts += [
                mk("rotation_ablation", sequence=n, rotations=r)
                for r in ["bmm", "organic"] + ["ground_truth"] * gt
            ]
        plan["rotation_ablation"] = ts
    if "noise" in only:
        plan["noise"] = [
            mk("noise", sequence=one, method=m, sigma=float(sg), run=r)
            for sg in s["noise_sigmas"]
            for m in s["noise_methods"]
            for r in range(s["noise_runs"])
        ]
    if "missing" in only:
        mseqs, frac = subset("missing_sequences"), float(s["missing_fraction"])
        ts = [mocap(n, m) for n in mseqs for m in s["missing_methods"]]
        ts += [
            mk("missing", sequence=n, method=m, pattern=pt, fraction=frac)
            for n in mseqs
            for pt in s["missing_patterns"]
            for m in s["missing_methods"]
        ]
        ts += [
            mk("missing", sequence=one, method=m, pattern="uniform", fraction=float(f))
            for f in s["curve_fractions"]
            for m in s["curve_methods"]
        ]
        for n in subset("track_sequences"):
            for pt in s["track_patterns"]:
                pt = check_choice("missing pattern", pt, PATTERNS)
                p = dict(fraction=float(s["track_fraction"]), drop_seed=int(s["track_seed"]))
                ts.append(mk("missing_tracks", sequence=n, pattern=pt, **p))
        plan["missing"] = ts
    if "n_ablation" in only:
        plan["n_ablation"] = [
            mk("n_ablation", sequence=n, Ns=list(s["Ns"])) for n in subset("ablation_sequences")
        ]
    if "k_sweep" in only:
        ts = []
        for n in subset("sweep_sequences"):
            seq = load_sequence(n, data)
            Kp, Km = paper_K(n), min(2 * seq.n_frames, seq.n_points) // 3
            if s["k_span"] is None:
                Ks = sorted({K for K in s["k_grid"] if K <= Km} | {Kp})
            else:
                Ks = [Kp + d for d in s["k_span"]]
            ts += [mk("k_sweep", sequence=n, K=int(K)) for K in Ks if 1 <= K <= Km]
        plan["k_sweep"] = ts
    if "shape" in only:
        rows = shape_rows(quick, find_external(external), mocap=data is not None)
        plan["shape"] = [mk("shape", row=r, column=c) for r in rows for c in SHAPE_COLUMNS]
    if "perspective" in only:
        rows = perspective_rows(quick, find_real(external))
        plan["perspective"] = [mk("perspective", row=r) for r in rows]
    return plan


def unique_tasks(plan):
    """All tasks of a plan once each, in first-seen order."""
    return list({t.key: t for ts in plan.values() for t in ts}.values())

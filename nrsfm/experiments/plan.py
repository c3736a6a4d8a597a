"""Which tasks make up each experiment, for the full and the quick set."""

from __future__ import annotations

from .tasks import AKHTER_ROTATIONS, Task

__all__ = ["EXPERIMENTS", "build_plan", "settings"]

#: experiment name -> what it regenerates
EXPERIMENTS = {
    "mocap": "MoCap table: organic, bmm, wnn at the paper's K; BMM at Dai's K beside the "
             "peer's run of Dai et al.'s code",
    "pseudo_inverse": "Table 1: rank-K pseudo-inverse shape (ground-truth rotations where "
                      "they exist)",
    "rotation_ablation": "Table 3: the organic shape stage on BMM, organic and "
                         "ground-truth rotations",
    "noise": "Fig. 3a-b: noise on pickup, e_R and e3d, mean and std over runs",
    "missing": "Fig. 3c: 30% missing (uniform and tracking) on every sequence, and a "
               "10-60% curve on pickup; the lost-tracks table (issue 24: e3d of the seen "
               "points, fill errors, the flag, a rigid-neighbour baseline) per pattern",
    "n_ablation": "Fig. 3d: the shape stage's N = 0..5",
    "k_sweep": "e3d as a function of K per sequence",
    "auto_k": "automatic K from W alone beside the paper's K",
    "shape": "the shape stage alone on ground-truth rotations, per formulation: clean and "
             "noisy MoCap, rank-deficient and exactly rank-K shapes, back with a moving "
             "camera (issue 22)",
}

_FULL = dict(methods=("organic", "organic-admm", "bmm", "wnn"),
             noise_sigmas=(0.01, 0.05, 0.1, 0.15, 0.2, 0.25),
             noise_runs=10, noise_methods=("organic", "organic-admm", "bmm", "wnn"),
             missing_methods=("organic", "bmm"), missing_patterns=("uniform", "tracking"),
             missing_fraction=0.3, curve_fractions=(0.1, 0.2, 0.3, 0.4, 0.5, 0.6),
             curve_methods=("organic", "bmm"), Ns=(0, 1, 2, 3, 4, 5),
             k_grid=(1, 2, 3, 4, 5, 6, 8, 10, 12, 14),
             k_span=None, ablation_sequences=None, sweep_sequences=None,
             missing_sequences=None,
             track_patterns=("uniform", "lost", "late", "block"), track_fraction=0.3,
             track_seed=31, track_sequences=("drink", "pickup", "yoga", "stretch"),
             noise_sequence="pickup", curve_sequence="pickup")

_QUICK = dict(_FULL, methods=("organic", "bmm"), noise_methods=("organic", "bmm", "wnn"),
              noise_sigmas=(0.01, 0.1, 0.25),
              noise_runs=2, curve_fractions=(0.1, 0.3, 0.5), curve_methods=("organic",),
              missing_patterns=("uniform", "tracking"), k_span=(-4, -2, 0),
              ablation_sequences=("pickup",), sweep_sequences=("pickup",),
              missing_sequences=("pickup",), track_patterns=("lost",),
              track_sequences=("pickup",))


def settings(quick=False):
    """The experiment settings (a dict) of the full or the quick set."""
    return dict(_QUICK if quick else _FULL)


def paper_K(name):
    import data_tools

    if name in data_tools.MOCAP_K:
        return data_tools.MOCAP_K[name]
    from .tasks import load_sequence

    return load_sequence(name).K


def _dai_K(name):
    import data_tools

    return data_tools.DAI_K.get(name, paper_K(name))


def _k_max(name, data):
    from .tasks import load_sequence

    seq = load_sequence(name, data)
    return min(2 * seq.n_frames, seq.n_points) // 3


def _checked(only, sequences, quick, overrides):
    """(experiments, sequences, settings) of :func:`build_plan`, checked."""
    import data_tools

    only = list(EXPERIMENTS) if not only else list(only)
    bad = [e for e in only if e not in EXPERIMENTS]
    if bad:
        raise ValueError(f"unknown experiment(s) {bad}; expected some of {list(EXPERIMENTS)}")
    seqs = list(sequences) if sequences else list(data_tools.MOCAP_NAMES)
    if not seqs:
        raise ValueError("no sequences given")
    s = settings(quick)
    bad = sorted(set(overrides or {}) - set(s))
    if bad:
        raise ValueError(f"unknown setting(s) {bad}; expected some of {sorted(s)}")
    s.update(overrides or {})
    return only, seqs, s


def _missing_tasks(mk, mocap, subset, s, one):
    """The missing experiment's tasks: the complete-data baselines, each pattern at the
    table's fraction, the curve on one sequence, the lost-tracks table's tasks."""
    from .missing_tracks import missing_track_tasks

    mseqs = subset("missing_sequences")
    ts = [mocap(n, m) for n in mseqs for m in s["missing_methods"]]
    ts += [mk("missing", sequence=n, method=m, pattern=pt,
              fraction=float(s["missing_fraction"]))
           for n in mseqs for pt in s["missing_patterns"] for m in s["missing_methods"]]
    ts += [mk("missing", sequence=one, method=m, pattern="uniform", fraction=float(f))
           for f in s["curve_fractions"] for m in s["curve_methods"]]
    return ts + missing_track_tasks(mk, subset("track_sequences"), s["track_patterns"],
                                    s["track_fraction"], s["track_seed"])


def build_plan(only=None, sequences=None, quick=False, data=None, seed=0, overrides=None,
               external=None):
    """Tasks of the selected experiments, without duplicates, in a stable order.

    Parameters
    ----------
    only : iterable of str, optional
        Experiment names (keys of :data:`EXPERIMENTS`); default all.
    sequences : iterable of str, optional
        Sequences (default: the 8 MoCap sequences). The noise and curve experiments use
        pickup when it is among them, else the first sequence.
    quick : bool
        The quick set (fewer methods, levels, runs and sequences for the ablations).
    data : str, optional
        Folder with the MoCap ``.mat`` files (passed to every task).
    seed : int
    overrides : dict, optional
        Replace some of the settings (:func:`settings`), e.g.
        ``{"missing_patterns": ("uniform",)}``.
    external : str, optional
        Folder of the external sequences (the ``shape`` experiment's ``back`` row); default
        :func:`nrsfm.experiments.shape.find_external` (``$NRSFM_EXTERNAL_DATA``, or
        ``external/`` beside ``mocap/``); no such row when none is found.

    Returns
    -------
    plan : dict experiment -> list of Task
        A task needed by several experiments (e.g. the complete-data baseline of the
        missing-data table) appears under each; :func:`unique_tasks` merges them.

    Raises
    ------
    ValueError
        Unknown experiment name, empty sequence list.
    """
    only, seqs, s = _checked(only, sequences, quick, overrides)
    data = None if data is None else str(data)
    one = s["noise_sequence"] if s["noise_sequence"] in seqs else seqs[0]

    def mk(exp, **p):
        return Task.make(exp, **p, seed=seed, data=data)

    def mocap(name, method, K=None):
        return mk("mocap", sequence=name, method=method,
                  K=int(paper_K(name) if K is None else K))

    def subset(key):
        return [n for n in seqs if s[key] is None or n in s[key]] or [one]

    plan = {}
    if "mocap" in only:
        ts = [mocap(n, m) for n in seqs for m in s["methods"]]
        ts += [mocap(n, "bmm", _dai_K(n)) for n in seqs]
        plan["mocap"] = ts
    if "pseudo_inverse" in only:
        plan["pseudo_inverse"] = [mk("pseudo_inverse", sequence=n) for n in seqs]
    if "rotation_ablation" in only:
        ts = []
        for n in subset("ablation_sequences"):
            srcs = ["bmm", "organic"] + (["ground_truth"] if n in AKHTER_ROTATIONS
                                         or n.startswith("synthetic-") else [])
            ts += [mk("rotation_ablation", sequence=n, rotations=r) for r in srcs]
        plan["rotation_ablation"] = ts
    if "noise" in only:
        plan["noise"] = [mk("noise", sequence=one, method=m, sigma=float(sg), run=r)
                         for sg in s["noise_sigmas"] for m in s["noise_methods"]
                         for r in range(s["noise_runs"])]
    if "missing" in only:
        plan["missing"] = _missing_tasks(mk, mocap, subset, s, one)
    if "n_ablation" in only:
        plan["n_ablation"] = [mk("n_ablation", sequence=n, Ns=list(s["Ns"]))
                              for n in subset("ablation_sequences")]
    if "k_sweep" in only:
        ts = []
        for n in subset("sweep_sequences"):
            Kp, Km = paper_K(n), _k_max(n, data)
            Ks = (sorted({K for K in s["k_grid"] if K <= Km} | {Kp}) if s["k_span"] is None
                  else [Kp + d for d in s["k_span"]])
            ts += [mk("k_sweep", sequence=n, K=int(K)) for K in Ks if 1 <= K <= Km]
        plan["k_sweep"] = ts
    if "auto_k" in only:
        plan["auto_k"] = ([mk("auto_k", sequence=n) for n in seqs]
                          + [mocap(n, "organic") for n in seqs])
    if "shape" in only:
        from .shape import shape_tasks

        plan["shape"] = shape_tasks(mk, quick, external, mocap=data is not None)
    return plan


def unique_tasks(plan):
    """All tasks of a plan once each, in first-seen order."""
    seen = {}
    for ts in plan.values():
        for t in ts:
            seen.setdefault(t.key, t)
    return list(seen.values())

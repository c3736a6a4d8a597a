"""Reconstructions for the lost-fill study (issue 24), cached so the fills can be compared
without re-running the pipeline: for each sequence, the organic pipeline at the paper's K on
the complete W and on W with each missing pattern and drop seed
(``data_tools.drop_tracks(W, 0.3, seed, pattern)``). One ``.npz`` per run in ``--cache``.

    OMP_NUM_THREADS=1 OPENBLAS_NUM_THREADS=1 python benchmarks/lost_fill_cache.py --cache DIR
"""

from __future__ import annotations

import argparse
import sys
import time
import warnings
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

SEQUENCES = ("drink", "pickup", "yoga", "stretch")
PATTERNS = ("lost", "late", "block")
SEEDS = (31, 7)


def cache_path(cache, name, pattern=None, seed=None):
    """The file of one run (``pattern=None``: complete data)."""
    tail = "complete" if pattern is None else f"{pattern}-{seed}"
    return Path(cache) / f"{name}-{tail}.npz"


def run_one(seq, W, path):
    """Reconstruct W (NaN = missing) and store rotations, shapes, W_completed, undetermined."""
    import nrsfm

    t0 = time.perf_counter()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        res = nrsfm.reconstruct(W, seq.K)
    secs = time.perf_counter() - t0
    extra = {}
    if res.observed is not None:
        extra = dict(W_completed=res.W_completed, undetermined=res.undetermined,
                     observed=res.observed)
    np.savez(path, rotations=res.rotations, shapes=res.shapes, W=res.W,
             row_means=res.row_means, secs=secs, **extra)
    return secs


def study_arguments(description, argv=None):
    """The options both lost-fill scripts take: the cache folder, the data folder, the
    sequences, patterns and seeds."""
    ap = argparse.ArgumentParser(description=description)
    ap.add_argument("--cache", required=True)
    ap.add_argument("--data", default=None)
    ap.add_argument("--sequences", nargs="+", default=SEQUENCES)
    ap.add_argument("--patterns", nargs="+", default=PATTERNS)
    ap.add_argument("--seeds", nargs="+", type=int, default=SEEDS)
    return ap.parse_args(argv)


def main(argv=None):
    import data_tools
    from nrsfm.experiments.tasks import load_sequence

    args = study_arguments(__doc__.splitlines()[0], argv)
    Path(args.cache).mkdir(parents=True, exist_ok=True)
    for name in args.sequences:
        seq = load_sequence(name, args.data)
        jobs = [(None, None, seq.W)]
        for pattern in args.patterns:
            for seed in args.seeds:
                jobs.append((pattern, seed,
                             data_tools.drop_tracks(seq.W, 0.3, seed=seed, pattern=pattern)[0]))
        for pattern, seed, W in jobs:
            path = cache_path(args.cache, name, pattern, seed)
            if path.exists():
                continue
            secs = run_one(seq, W, path)
            print(f"{name} {pattern or 'complete'} {seed or ''}: {secs:.1f} s", flush=True)


if __name__ == "__main__":
    main()

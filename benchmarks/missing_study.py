"""Missing data at scale: the rank-r factorisation of the observed entries against complete
tracks (and the soft-impute completion). Prints two tables.

1. Dense synthetic tracks (issue 16, acceptance 1): P points x F frames from a random
   rank-3K shape basis (K bases of 3 x P, smooth coefficients) under a smooth orthographic
   camera, noise as a fraction of W's mean row std; ``--lost`` of the tracks are lost from
   a frame drawn in [2, F) to the end, ``--late`` start at a frame drawn in [0, F - 2)
   (NaN before). Same data reconstructed with complete tracks and with the missing
   entries (``nrsfm.reconstruct``'s default completion), in one run: time, e3d over all
   points, and e3d over the tracks the data determine (``Reconstruction.undetermined``:
   fill gain <= ``MAX_GAIN``) beside the complete-track e3d on the same points.
2. MoCap (issue 16, acceptance 2; needs NRSFM_DATA): 30 % missing in the tracking pattern
   and uniformly at random (``data_tools.drop_tracks``, seed 0), organic at the paper's K:
   e3d of complete data and of ``nrsfm.reconstruct`` with each completion
   (``MeasurementSettings.completion``: the factorisation and soft-impute; the default
   ``auto`` takes soft-impute on MoCap), lags by the rule of
   ``nrsfm.stages.completion.choose_lags``.
3. Synthetic videos (``data_tools.synthetic_video``, sheet and face), sparse and dense
   tracks with new tracks every ``--detect-every`` frames: ``reconstruct_tracks`` (the
   path of ``nrsfm video``) on the complete tracks alone against every track seen in 2+
   frames (reconstruct's default completion), K = 1.

    Run from the repository root, one BLAS thread:
    OMP_NUM_THREADS=1 OPENBLAS_NUM_THREADS=1 python benchmarks/missing_study.py
    python benchmarks/missing_study.py --skip-mocap --points 2000
"""

from __future__ import annotations

import argparse
import os
import sys
import time
import warnings
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

import nrsfm  # noqa: E402
from data_tools.synthetic import camera_rotations  # noqa: E402
from nrsfm.metrics import e3d  # noqa: E402
from nrsfm.stages.completion import MAX_GAIN  # noqa: E402


def dense_sequence(P, F, K, noise, lost, late, seed, parts=False):
    """Synthetic dense tracks with lost and late tracks.

    Returns
    -------
    W : (2F, P) ndarray
        Complete noisy measurements (per-frame translation included).
    observed : (F, P) bool ndarray
    shapes : (F, 3, P) ndarray
        Ground truth in the camera frame, centred per frame.
    model : dict
        Only with ``parts``: the generator's ``rotations`` (F, 3, 3), ``coefficients``
        (F, K), ``basis`` (K, 3, P), the std of the basis entries ``basis_std`` (K, 3) and
        the uncentred ``camera_shapes`` ``R_f sum_k c_fk S_k`` (F, 3, P).
    """
    rng = np.random.default_rng(seed)
    axes, deform = np.array([1.0, 0.8, 0.6]), 0.4
    basis = rng.standard_normal((K, 3, P)) * axes[:, None]
    basis[1:] *= deform
    std = axes[None, :] * np.r_[1.0, [deform] * (K - 1)][:, None]                 # (K, 3)
    t = np.arange(F)[:, None]
    coeff = np.sin(2 * np.pi * rng.uniform(1, 4, (1, K)) * t / F
                   + rng.uniform(0, 2 * np.pi, (1, K)))
    coeff[:, 0] = 1.0 + 0.1 * coeff[:, 0]
    R = camera_rotations(F, "smooth", rng)
    cam = R @ np.einsum("fk,kip->fip", coeff, basis)
    W = cam[:, :2].reshape(2 * F, P) + 3.0 * rng.standard_normal((2 * F, 1))
    W = W + noise * np.mean(np.std(W, axis=1)) * rng.standard_normal(W.shape)
    observed = np.ones((F, P), bool)
    order = rng.permutation(P)
    n_lost, n_late = int(round(lost * P)), int(round(late * P))
    frames = np.arange(F)[:, None]
    lost_p, late_p = order[:n_lost], order[n_lost:n_lost + n_late]
    observed[:, lost_p] = frames < rng.integers(2, F, n_lost)[None, :]
    observed[:, late_p] = frames >= rng.integers(0, F - 2, n_late)[None, :]
    out = (W, observed, cam - cam.mean(axis=2, keepdims=True))
    model = dict(rotations=R, coefficients=coeff, basis=basis, basis_std=std, camera_shapes=cam)
    return out + (model,) if parts else out


def with_nan(W, observed):
    """Copy of W with NaN where a point is not observed."""
    return np.where(np.repeat(observed, 2, axis=0), W, np.nan)


def dense_table(args):
    P, F, K = args.points, args.frames, args.K
    W, observed, gt = dense_sequence(P, F, K, args.noise, args.lost, args.late, args.seed)
    Wm = with_nan(W, observed)
    nrsfm.reconstruct(W, K)             # untimed: the first call of a process pays its set-up
    nrsfm.reconstruct(Wm, K)            # (imports, first touch of memory), for both runs
    t_full, t_miss, t_comp = [], [], []
    for _ in range(args.repeats):       # in turn, the medians
        t0 = time.perf_counter()
        full = nrsfm.reconstruct(W, K)
        t_full.append(time.perf_counter() - t0)
        t0 = time.perf_counter()
        res = nrsfm.reconstruct(Wm, K)                         # the default completion
        t_miss.append(time.perf_counter() - t0)
        t_comp.append(res.timings["completion"])
    ratio = float(np.median(np.divide(t_miss, t_full)))
    t_full, t_miss, t_comp = (float(np.median(t)) for t in (t_full, t_miss, t_comp))
    comp = res.completion
    det = ~res.undetermined
    e_full, e_all = e3d(full.shapes, gt), e3d(res.shapes, gt)
    e_full_det = e3d(full.shapes[:, :, det], gt[:, :, det])
    e_det = e3d(res.shapes[:, :, det], gt[:, :, det])
    print(f"\nTable 1: dense synthetic tracks, P = {P}, F = {F}, K = {K}, noise "
          f"{100 * args.noise:g} %, {100 * args.lost:g} % lost, {100 * args.late:g} % late, "
          f"seed {args.seed}; {100 * comp.missing_fraction:.1f} % of the observations "
          f"missing\n")
    print(f"(seconds and ratio: medians of {args.repeats} runs of each, in turn, after one "
          f"untimed run of each)\n")
    print("| run | seconds | ratio to complete | e3d all points | e3d determined tracks "
          "| complete-track e3d, same tracks | bound 1.2 x + .002 |")
    print("|---|---|---|---|---|---|---|")
    print(f"| complete tracks | {t_full:.2f} | 1 | {e_full:.4f} | - | - | - |")
    print(f"| missing: completion ({comp.n_iter} iterations, lags {comp.lags}, "
          f"{t_comp:.1f} s) + pipeline "
          f"| {t_miss:.2f} | {ratio:.2f} | {e_all:.4f} | {e_det:.4f} "
          f"({det.sum()} of {P}) | {e_full_det:.4f} | {1.2 * e_full_det + 0.002:.4f} |")
    nobs = observed.sum(axis=0)
    print(f"\nundetermined tracks (fill gain > {MAX_GAIN:g}): {P - det.sum()}, observed in "
          f"{nobs[~det].min() if (~det).any() else '-'} to "
          f"{nobs[~det].max() if (~det).any() else '-'} frames; determined tracks: at least "
          f"{nobs[det].min()} frames")


def mocap_table(args):
    import data_tools as dt
    from nrsfm.settings import MeasurementSettings, Settings

    rows = []
    for name in args.sequences:
        seq = dt.load_mocap(name)
        K = seq.K
        e0 = nrsfm.reconstruct(seq.W, K).errors(seq.shapes)["e3d"]
        for pattern in args.patterns:
            Wm, mask = dt.drop_tracks(seq.W, args.fraction, seed=args.seed, pattern=pattern)
            row = [name, pattern, K, e0]
            for completion in args.completions:
                s = Settings(measurement=MeasurementSettings(completion=completion))
                t0 = time.perf_counter()
                r = nrsfm.reconstruct(Wm, K, settings=s)
                e = r.errors(seq.shapes)["e3d"]
                row += [e, e / e0, time.perf_counter() - t0, r.timings["completion"],
                        r.completion.n_iter, r.completion.lags]
            rows.append(row)
            print(f"  {name} {pattern} done", file=sys.stderr, flush=True)
    print(f"\nTable 2: MoCap, {100 * args.fraction:g} % missing, seed {args.seed}, organic "
          f"at the paper's K, nrsfm.reconstruct with each completion (lags by the rule)\n")
    head = " | ".join(f"{c}: e3d (x), s total (completion, iterations, lags)"
                      for c in args.completions)
    print(f"| sequence | pattern | K | complete e3d | {head} |")
    print("|---|---|---|---|" + "---|" * len(args.completions))
    for name, pat, K, e0, *res in rows:
        cells = [f"{res[i]:.4f} ({res[i + 1]:.2f}), {res[i + 2]:.1f} ({res[i + 3]:.1f}, "
                 f"{res[i + 4]}, {res[i + 5]})" for i in range(0, len(res), 6)]
        print(f"| {name} | {pat} | {K} | {e0:.4f} | " + " | ".join(cells) + " |")


def video_table(args):
    from data_tools.synthetic_video import make_video
    from data_tools.video import track_dense, track_sparse

    rows = []
    for surface in args.surfaces:
        v = make_video(surface, n_frames=args.video_frames, seed=args.seed)
        for kind in args.kinds:
            t0 = time.perf_counter()
            tr = (track_sparse(v.frames, detect_every=args.detect_every) if kind == "sparse"
                  else track_dense(v.frames, step=4, detect_every=args.detect_every))
            t_track = time.perf_counter() - t0
            rows.append((surface, kind, tr, t_track, *video_runs(v, tr)))
            print(f"  {surface} {kind} done", file=sys.stderr, flush=True)
    print(f"\nTable 3: synthetic videos, {args.video_frames} frames, new tracks every "
          f"{args.detect_every} frames, K = 1, nrsfm.tracks.reconstruct_tracks (the path of "
          f"nrsfm video); e3d against the ground truth of every used track on the surface "
          f"(late tracks located in their first frame)\n")
    print("| video | tracks | complete | lost | late | track s | --complete-tracks: s, e3d "
          "| all tracks (2+ frames): s, e3d | e3d on the complete tracks | e3d on the "
          "determined tracks | undetermined |")
    print("|---|---|---|---|---|---|---|---|---|---|---|")
    for surface, kind, tr, tt, tc, ec, ta, ea, eac, ead, nu in rows:
        F = tr.n_frames
        print(f"| {surface} {kind} | {tr.n_points} | {int(tr.complete.sum())} | "
              f"{int((tr.lost_at < F).sum())} | {int((tr.start > 0).sum())} | {tt:.1f} | "
              f"{tc:.1f}, {ec:.4f} | {ta:.1f}, {ea:.4f} | {eac:.4f} | {ead:.4f} | {nu} |")


def video_runs(v, tr):
    """``--complete-tracks`` against every track seen in 2+ frames (the default), on one
    tracked video: seconds and e3d of each; for the latter also e3d on the complete tracks
    and on the tracks the data determine, and how many are undetermined."""
    from nrsfm.tracks import reconstruct_tracks

    gt = v.ground_truth(tr.tracks)
    cam = v.pixel_scale * gt["camera"]                         # (F, 3, P), NaN off-surface
    ok = gt["valid"]
    out = []
    for missing in ("complete", "auto"):
        t0 = time.perf_counter()
        vr = reconstruct_tracks(tr.W, 1, missing=missing)
        out.append(time.perf_counter() - t0)
        cols = np.flatnonzero(vr.used)
        keep = ok[cols]
        X, G = vr.result.shapes[:, :, keep], cam[:, :, cols[keep]]
        out.append(e3d(X, G))
    comp = tr.complete[cols[keep]]
    det = ~vr.result.undetermined[keep]
    out += [e3d(X[:, :, comp], G[:, :, comp]), e3d(X[:, :, det], G[:, :, det]),
            int(vr.result.undetermined.sum())]
    return out


def main(argv=None):
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--points", type=int, default=20000)
    p.add_argument("--frames", type=int, default=100)
    p.add_argument("--K", type=int, default=2)
    p.add_argument("--noise", type=float, default=0.005)
    p.add_argument("--lost", type=float, default=0.2)
    p.add_argument("--late", type=float, default=0.1)
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--repeats", type=int, default=3, help="timed runs of each (dense table)")
    p.add_argument("--fraction", type=float, default=0.3, help="MoCap missing fraction")
    p.add_argument("--patterns", nargs="+", default=["tracking", "uniform"])
    p.add_argument("--completions", nargs="+", default=["factorisation", "soft_impute"])
    p.add_argument("--sequences", nargs="+", default=["drink", "pickup", "yoga", "stretch"])
    p.add_argument("--surfaces", nargs="+", default=["sheet", "face"])
    p.add_argument("--kinds", nargs="+", default=["sparse", "dense"])
    p.add_argument("--video-frames", type=int, default=100)
    p.add_argument("--detect-every", type=int, default=5)
    p.add_argument("--skip-dense", action="store_true")
    p.add_argument("--skip-video", action="store_true")
    p.add_argument("--skip-mocap", action="store_true")
    args = p.parse_args(argv)
    warnings.simplefilter("ignore", RuntimeWarning)
    print(f"threads: OMP_NUM_THREADS={os.environ.get('OMP_NUM_THREADS')}; timings on a "
          f"shared 2-core machine")
    tables = ((args.skip_dense, dense_table), (args.skip_mocap, mocap_table),
              (args.skip_video, video_table))
    for table in (table for skip, table in tables if not skip):
        table(args)


if __name__ == "__main__":
    main()

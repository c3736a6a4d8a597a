"""Study of the noise-constrained organic shape solver (nrsfm/stages/shape/constrained.py).

Prints tables; every figure in ``docs/shape_constrained.md`` comes from one section:

    NRSFM_DATA=/path/to/data python benchmarks/shape_study_constrained.py --sections gt
    python benchmarks/shape_study_constrained.py --sections synthetic deficient reproject

Sections: ``gt`` (MoCap, ground-truth rotations: today's default, the paper's ADMM and the
new solver, with shape-stage times side by side), ``synthetic`` (noise-free rank-K data,
K = 1..8, three scales), ``deficient`` (rigid body plus a planar deformation, W of rank 5),
``reproject`` (MoCap ground-truth shapes seen by new cameras, noise 0 - 5 %),
``stability`` (pipeline rotations held fixed, four 1e-7 perturbations of W), ``noise``
(pickup, ground-truth rotations), ``variants`` (eps rule and continuation constants),
``noise_kkt`` (pickup sigma .10: default, ADMM end point, certified KKT point, ground-truth
and pipeline rotations), ``drink_kkt`` (drink's distinct certified KKT points under 1e-7
perturbations). ``gt`` shows the ADMM's end point (``polish=False``) and the certified
KKT point side by side.
"""

from __future__ import annotations

import argparse
import os
import sys
import time

import numpy as np
from threadpoolctl import threadpool_limits

import data_tools as dt
import nrsfm
from nrsfm.metrics import e3d
from nrsfm.stages.shape.constrained import ConstrainedSettings, organic_fit

AKHTER4 = ("drink", "pickup", "yoga", "stretch")


def _fit(W, R, K, **kw):
    """The constrained solver's result, its settings as keywords."""
    return organic_fit(W, R, K, ConstrainedSettings(**kw))


def new_shapes(W, R, K, **kw):
    """Shapes of the new solver (W in any units; the solver is scale-free)."""
    return _fit(W, R, K, **kw).shapes


def old_shapes(W, R, K, solver):
    """Shapes of today's solvers through the pipeline with the rotations given."""
    return nrsfm.reconstruct(W, K, rotations=R, shape_solver=solver).shapes


def _timed(fn):
    t0 = time.perf_counter()
    out = fn()
    return out, time.perf_counter() - t0


def rank_deficient(F=80, P=30, K=2, motion="smooth", seed=0):
    """(W, R, X_world) of :func:`data_tools.make_rank_deficient` (W of rank 5)."""
    seq = dt.make_rank_deficient(F, P, motion, seed)
    return seq.W, seq.rotations, seq.world_shapes


def section_gt(seqs):
    print("\n== MoCap, ground-truth rotations: e3d (shape-stage seconds, side by side, one "
          "BLAS thread, shared machine) ==")
    print(f"{'seq':8s} {'K':>3s} {'bilinear':>16s} {'admm':>16s} {'ADMM end point':>16s} "
          f"{'certified KKT':>16s}  objective end point / KKT, r, L-BFGS its, certified")
    for name in AKHTER4:
        seq = seqs[name]
        cells = []
        for solver in ("bilinear", "admm"):
            rec = nrsfm.reconstruct(seq.W, seq.K, rotations=seq.rotations, shape_solver=solver)
            cells.append(f"{e3d(rec.shapes, seq.shapes):.4f} ({rec.timings['shape']:5.2f})")
        for polish in (False, True):
            res, secs = _timed(lambda: _fit(seq.W, seq.rotations, seq.K,
                                                             polish=polish))
            cells.append(f"{e3d(res.shapes, seq.shapes):.4f} ({secs:5.2f})")
        k = res.kkt
        print(f"{name:8s} {seq.K:3d} " + " ".join(f"{c:>16s}" for c in cells)
              + f"  {res.candidate_objectives['admm']:.4g} / {res.objective:.4g}, "
              f"{k.get('rank')}, {k.get('n_iter')}, {res.certified}", flush=True)


def section_synthetic():
    print("\n== noise-free, exactly rank K, ground-truth rotations: max e3d over motions "
          "(smooth, fast, random) and scales (1e-3, 1, 1e3) ==")
    print(f"{'K':>3s} {'F':>4s} {'P':>4s} {'organic_fit':>12s} {'max spread over scales':>24s}")
    for K in range(1, 9):
        F, P = 60, max(3 * K + 2, 20)
        worst, spread = 0.0, 0.0
        for motion in ("smooth", "fast", "random"):
            seq = dt.make_synthetic(F=F, P=P, K=K, motion=motion, seed=10 + K)
            errs = [e3d(new_shapes(c * seq.W, seq.rotations, K), seq.shapes)
                    for c in (1e-3, 1.0, 1e3)]
            worst = max(worst, max(errs))
            spread = max(spread, max(errs) - min(errs))
        print(f"{K:3d} {F:4d} {P:4d} {worst:12.1e} {spread:24.1e}", flush=True)


def section_deficient():
    print("\n== rank-deficient: rigid body + planar deformation (rank W = 5, true K = 2), "
          "ground-truth rotations: e3d at scales 1e-3 / 1 / 1e3 ==")
    print(f"{'motion':8s} {'K':>3s} {'organic_fit':>30s} {'bilinear':>30s}")
    for motion in ("smooth", "random"):
        W, R, X = rank_deficient(motion=motion)
        gt = R @ X
        for K in (2, 3):
            new = [e3d(new_shapes(c * W, R, K), gt) for c in (1e-3, 1.0, 1e3)]
            with np.errstate(all="ignore"):
                import warnings
                with warnings.catch_warnings():
                    warnings.simplefilter("ignore")
                    old = [e3d(old_shapes(c * W, R, K, "bilinear"), gt) for c in (1e-3, 1.0, 1e3)]
            print(f"{motion:8s} {K:3d} " + f"{' / '.join(f'{v:.1e}' for v in new):>30s} "
                  + f"{' / '.join(f'{v:.1e}' for v in old):>30s}", flush=True)


def reprojected(seq, motion, noise, seed):
    """The sequence's ground-truth world-frame shapes (``R_gt' shapes``) seen by a new
    camera path."""
    rng = np.random.default_rng(seed)
    R = dt.camera_rotations(seq.n_frames, motion, rng)
    world = seq.rotations.transpose(0, 2, 1) @ seq.shapes
    world = world - world.mean(axis=2, keepdims=True)
    W = (R[:, :2] @ world).reshape(2 * seq.n_frames, -1)
    if noise:
        W = dt.add_noise(W, noise, seed=seed)
    return W, R, R @ world


def section_reproject(seqs):
    print("\n== MoCap ground-truth shapes re-projected by new cameras, ground-truth "
          "rotations, noise sigma x mean row std of W (seed 0): e3d bilinear / admm / "
          "organic_fit ==")
    for name in ("pickup", "stretch"):
        seq = seqs[name]
        for motion in ("smooth", "fast", "random"):
            row = []
            for noise in (0.0, 0.01, 0.05):
                W, R, gt = reprojected(seq, motion, noise, 0)
                vals = [e3d(old_shapes(W, R, seq.K, s), gt) for s in ("bilinear", "admm")]
                vals.append(e3d(new_shapes(W, R, seq.K), gt))
                mark = "*" if vals[2] <= min(vals[:2]) else " "
                row.append(" / ".join(f"{v:.4f}" for v in vals) + mark)
            print(f"{name:8s} {motion:7s} " + "  ".join(row), flush=True)
    print("(* = organic_fit at or below the better of the two; columns: noise 0, .01, .05)")


def section_stability(mocap, names, draws=4):
    print("\n== pipeline rotations held fixed (res = nrsfm.reconstruct(W, K)); e3d of W and "
          f"of {draws} draws of a 1e-7 relative perturbation; spread (max-min)/min ==")
    for name in names:
        seq = dt.load_mocap(name, mocap)
        R = nrsfm.reconstruct(seq.W, seq.K).rotations
        rms = float(np.sqrt(np.mean(seq.W ** 2)))
        vals = []
        for d in range(draws + 1):
            W = seq.W
            if d:
                W = W + 1e-7 * rms * np.random.default_rng(d).standard_normal(W.shape)
            vals.append(e3d(new_shapes(W, R, seq.K), seq.shapes))
        v = np.asarray(vals)
        spread = (v.max() - v.min()) / v.min()
        print(f"{name:8s} e3d {v[0]:.4f} | " + " ".join(f"{x:.4f}" for x in v[1:])
              + f"  spread {100 * spread:5.2f}%", flush=True)


def section_noise(seqs, runs=1):
    seq = seqs["pickup"]
    sig = (0.0, 0.01, 0.05, 0.1, 0.2)
    print(f"\n== pickup, ground-truth rotations, noise sigma x mean row std of W, mean of "
          f"{runs} seeds: e3d ==")
    print(f"{'solver':22s} " + " ".join(f"{format(s, 'g'):>7s}" for s in sig))
    for solver in ("bilinear", "admm", "organic_fit", "organic_fit/rank3k-eps"):
        vals = []
        for g in sig:
            errs = []
            for seed in (range(runs) if g else [0]):
                W = dt.add_noise(seq.W, g, seed=seed) if g else seq.W
                if solver == "organic_fit":
                    X = new_shapes(W, seq.rotations, seq.K)
                elif solver == "organic_fit/rank3k-eps":
                    X = new_shapes(W, seq.rotations, seq.K, eps=rank3k_residual(W, seq.K))
                else:
                    X = old_shapes(W, seq.rotations, seq.K, solver)
                errs.append(e3d(X, seq.shapes))
            vals.append(float(np.mean(errs)))
        print(f"{solver:22s} " + " ".join(f"{v:7.4f}" for v in vals), flush=True)


def rank3k_residual(W, K):
    """||W - W_3K||_F: the residual of the best rank-3K approximation (the alternative
    eps rule: the smallest residual a rank-K shape can leave)."""
    s = np.linalg.svd(W, compute_uv=False)
    return float(np.sqrt(np.sum(s[3 * K:] ** 2)))


def section_variants(seqs):
    print("\n== variants (ground-truth rotations): eps rule x continuation constants ==")
    rows = [("eps=noise norm, rho0=1, lam=1.1", {}),
            ("eps=0 (exact fit)", dict(eps=0.0)),
            ("eps=||W-W_3K||", "rank3k"),
            ("rho0=0.1", dict(rho0=0.1)), ("rho0=10", dict(rho0=10.0)),
            ("lam=1.05", dict(lam=1.05)), ("lam=1.2", dict(lam=1.2))]
    print(f"{'variant':34s} " + " ".join(f"{n:>8s}" for n in AKHTER4))
    for label, kw in rows:
        vals = []
        for n in AKHTER4:
            seq = seqs[n]
            opts = dict(eps=rank3k_residual(seq.W, seq.K)) if kw == "rank3k" else kw
            vals.append(e3d(new_shapes(seq.W, seq.rotations, seq.K, **opts), seq.shapes))
        print(f"{label:34s} " + " ".join(f"{v:8.4f}" for v in vals), flush=True)


def section_flat(seqs, name="drink", draws=4):
    print(f"\n== {name}, ground-truth rotations, W and {draws} draws of a 1e-7 relative "
          "perturbation: e3d and objective / ||W||_F, for two continuation rates ==")
    seq = seqs[name]
    rms = float(np.sqrt(np.mean(seq.W ** 2)))
    for lam in (1.1, 1.05):
        e, o = [], []
        for d in range(draws + 1):
            W = seq.W
            if d:
                W = W + 1e-7 * rms * np.random.default_rng(d).standard_normal(W.shape)
            res = _fit(W, seq.rotations, seq.K, lam=lam)
            e.append(e3d(res.shapes, seq.shapes))
            o.append(res.objective / np.linalg.norm(W))
        print(f"lam {lam}: e3d " + " ".join(f"{v:.4f}" for v in e) + " | objective "
              + " ".join(f"{v:.2f}" for v in o), flush=True)


def section_pipeline_noise(seqs, sigmas=(0.01, 0.05, 0.10, 0.20), seeds=2):
    print(f"\n== pickup, full pipeline under noise (the noise study's protocol, {seeds} seeds): "
          "e3d of method='bmm', of method='organic' with today's shape stage, and of "
          "organic_fit on the organic pipeline's rotations ==")
    import warnings
    seq = seqs["pickup"]
    print(f"{'sigma':>6s} {'bmm':>8s} {'organic':>8s} {'organic_fit':>12s}")
    for sigma in sigmas:
        vals = {k: [] for k in ("bmm", "organic", "organic_fit")}
        for seed in range(seeds):
            W = dt.add_noise(seq.W, sigma, seed=seed)
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")
                org = nrsfm.reconstruct(W, seq.K, seed=seed)
                bmm = nrsfm.reconstruct(W, seq.K, method="bmm", seed=seed)
            vals["organic"].append(e3d(org.shapes, seq.shapes))
            vals["bmm"].append(e3d(bmm.shapes, seq.shapes))
            vals["organic_fit"].append(e3d(new_shapes(org.W, org.rotations, seq.K), seq.shapes))
        print(f"{sigma:6.2f} " + " ".join(f"{np.mean(vals[k]):{w}.4f}" for k, w in
                                          (("bmm", 8), ("organic", 8), ("organic_fit", 12))),
              flush=True)


def section_noise_kkt(seqs, sigma=0.10, seeds=2):
    print(f"\n== pickup, noise sigma {sigma} (add_noise, seeds 0 - {seeds - 1}), ground-truth "
          "rotations and the organic pipeline's rotations: mean e3d of today's default, the "
          "ADMM end point and the certified KKT point (shape-stage seconds side by side) ==")
    import warnings
    seq = seqs["pickup"]
    for label in ("ground-truth", "pipeline"):
        vals = {k: [] for k in ("default", "end point", "KKT")}
        secs = {k: 0.0 for k in vals}
        for seed in range(seeds):
            W = dt.add_noise(seq.W, sigma, seed=seed)
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")
                rec = nrsfm.reconstruct(W, seq.K, seed=seed) if label == "pipeline" else \
                    nrsfm.reconstruct(W, seq.K, rotations=seq.rotations)
            vals["default"].append(e3d(rec.shapes, seq.shapes))
            secs["default"] += rec.timings["shape"]
            for key, polish in (("end point", False), ("KKT", True)):
                res, t = _timed(lambda: _fit(rec.W, rec.rotations, seq.K,
                                                              polish=polish))
                vals[key].append(e3d(res.shapes, seq.shapes))
                secs[key] += t
        print(f"{label:12s} " + "  ".join(f"{k} {np.mean(v):.4f} ({secs[k] / seeds:.2f} s)"
                                          for k, v in vals.items()), flush=True)


def section_drink_kkt(mocap, draws=1, gtols=(1e-8, 1e-10)):
    print(f"\n== drink, pipeline rotations held fixed, W and {draws} draws of a 1e-7 relative "
          "perturbation: certified KKT points (objective / ||W||, e3d, r, L-BFGS iterations, "
          "relative gradient, rank certificate) ==")
    seq = dt.load_mocap("drink", mocap)
    R = nrsfm.reconstruct(seq.W, seq.K).rotations
    rms = float(np.sqrt(np.mean(seq.W ** 2)))
    for gtol in gtols:
        for d in range(draws + 1):
            W = seq.W
            if d:
                W = W + 1e-7 * rms * np.random.default_rng(d).standard_normal(W.shape)
            res = _fit(W, R, seq.K, gtol=gtol, polish_max_iter=8000)
            k, nw = res.kkt, np.linalg.norm(W)
            print(f"gtol {gtol:.0e} draw {d}: objective {res.objective / nw:.5f} (end point "
                  f"{res.candidate_objectives['admm'] / nw:.5f}), e3d "
                  f"{e3d(res.shapes, seq.shapes):.4f}, r {k['rank']}, {k['n_iter']} its, "
                  f"gradient {k['grad_norm']:.1e}, rank certificate "
                  f"{k['rank_certificate']:.2f}, certified {res.certified}", flush=True)


def section_dense():
    print("\n== dense: K = 1, F = 100, P = 30,000, 1 % noise, ground-truth rotations: shape "
          "stage alone ==")
    seq = dt.make_synthetic(F=100, P=30000, K=1, motion="smooth", noise=0.01, seed=0)
    res, secs = _timed(lambda: _fit(seq.W, seq.rotations, 1))
    print(f"organic_fit {secs:.2f} s, {res.n_iter} iterations, e3d "
          f"{e3d(res.shapes, seq.shapes):.4f}, chosen {res.chosen}", flush=True)


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--data", default=os.environ.get("NRSFM_DATA"),
                    help="the folder that holds mocap/, or mocap/ itself (default: $NRSFM_DATA)")
    secs = ["gt", "synthetic", "deficient", "reproject", "stability", "noise", "variants",
            "dense", "flat", "pipeline_noise", "noise_kkt", "drink_kkt"]
    ap.add_argument("--sections", nargs="+", default=["gt", "synthetic", "deficient"],
                    choices=secs)
    ap.add_argument("--sequences", nargs="+", default=list(dt.MOCAP_NAMES))
    args = ap.parse_args(argv)
    needs = set(args.sections) - {"synthetic", "deficient", "dense"}
    if needs and not args.data:
        ap.error("no data folder: pass --data or set NRSFM_DATA")
    mocap = args.data
    with threadpool_limits(limits=1):
        seqs = {n: dt.load_mocap(n, mocap) for n in AKHTER4} if needs else {}
        for sec in args.sections:
            if sec == "gt":
                section_gt(seqs)
            elif sec == "synthetic":
                section_synthetic()
            elif sec == "deficient":
                section_deficient()
            elif sec == "reproject":
                section_reproject(seqs)
            elif sec == "stability":
                section_stability(mocap, args.sequences)
            elif sec == "noise":
                section_noise(seqs)
            elif sec == "variants":
                section_variants(seqs)
            elif sec == "dense":
                section_dense()
            elif sec == "flat":
                section_flat(seqs)
            elif sec == "pipeline_noise":
                section_pipeline_noise(seqs)
            elif sec == "noise_kkt":
                section_noise_kkt(seqs)
            elif sec == "drink_kkt":
                section_drink_kkt(mocap)


if __name__ == "__main__":
    main()

"""From a synthetic video to 3D, and the pipeline at dense scale. Prints two tables.

1. Tracking and reconstruction on rendered synthetic videos (``data_tools.synthetic_video``:
   a bent waving sheet and a breathing face-like surface, 100 frames of 640 x 480): the
   tracking error in pixels against the true projections of the tracked surface points, the
   identity swaps (a track more than ``--swap-px`` off its true position) and how many the
   forward-backward check caught (stopped at or before the frame the unchecked track first
   drifts), and e3d of the sparse and dense reconstructions (K = 1, complete tracks).
2. Per-stage time and peak memory (tracemalloc) of the pipeline on noise-free dense tracks:
   P points drawn uniformly on the face mesh, F frames, K = 1: factorisation (numpy's thin
   SVD of the 2F x P W, and the same through the 2F x 2F Gram matrix), rotation stage,
   pseudo-inverse shape, shape stage (``--shape-solver``, default bilinear), the whole
   pipeline ``nrsfm.reconstruct(W, 1)``, and the recording.

    NRSFM_DATA unused. Run from the repository root:
    OMP_NUM_THREADS=1 python benchmarks/dense_benchmark.py                 # both tables
    python benchmarks/dense_benchmark.py --skip-video --points 70000 --frames 80
"""

from __future__ import annotations

import argparse
import os
import resource
import sys
import tempfile
import time
import tracemalloc
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

import nrsfm  # noqa: E402
from data_tools.synthetic_video import make_video, tracking_errors  # noqa: E402
from data_tools.video import Tracks, track_dense, track_sparse  # noqa: E402
from nrsfm.tracks import reconstruct_tracks  # noqa: E402


def _measure(fn):
    """Run fn(); return (value, seconds, peak MB of Python/numpy allocations)."""
    tracemalloc.start()
    tracemalloc.reset_peak()
    t0 = time.perf_counter()
    out = fn()
    dt = time.perf_counter() - t0
    peak = tracemalloc.get_traced_memory()[1] / 1e6
    tracemalloc.stop()
    return out, dt, peak


def video_table(args):
    rows, exact = [], []
    for surface in args.surfaces:
        v = make_video(surface, n_frames=args.video_frames, seed=args.seed)
        for kind in ("sparse", "dense"):
            t0 = time.perf_counter()
            if kind == "sparse":
                tr = track_sparse(v.frames, keep_raw=True)
            else:
                tr = track_dense(v.frames, step=args.step, keep_raw=True)
            t_track = time.perf_counter() - t0
            rep = tracking_errors(v, tr, swap_px=args.swap_px)
            seq = v.sequence(tr.tracks)
            vr, t_rec, _ = _measure(lambda: reconstruct_tracks(seq.W, 1))
            gt = seq.shapes[:, :, vr.used]
            e = vr.result.errors(gt)["e3d"]
            rows.append((surface, kind, rep, e, vr, t_track, t_rec))
            print(f"  {surface} {kind}: done ({t_track:.1f} s tracking, {t_rec:.1f} s "
                  f"reconstruction)", file=sys.stderr, flush=True)
        # no tracker: exact projections of the surface points under the mesh vertices'
        # pixels in frame 0 (a hidden vertex is replaced by the point that hides it)
        gt = v.ground_truth(v.project(v.vertices))
        seq = v.sequence(gt["pixels"][:, :, gt["valid"]])
        vr, t_rec, _ = _measure(lambda: reconstruct_tracks(seq.W, 1))
        e_exact = vr.result.errors(seq.shapes[:, :, vr.used])["e3d"]
        exact.append((surface, seq.n_points, e_exact, t_rec))
    print(f"\nTable 1: synthetic videos, {args.video_frames} frames 640x480, seed "
          f"{args.seed}, swap = more than {args.swap_px} px off, K = 1, organic, complete "
          f"tracks\n")
    print("| surface | tracker | tracks | on surface | complete | err median px | err p95 px "
          "| drift (unchecked) | caught | caught % | swapped & kept | stopped clean "
          "| e3d | track s | reconstruct s |")
    print("|" + "---|" * 15)
    for surface, kind, r, e, vr, tt, tr_ in rows:
        print(f"| {surface} | {kind} | {r['n_tracks']} | {r['n_on_surface']} | "
              f"{r['n_complete']} | {r['error_median']:.3f} | {r['error_p95']:.3f} | "
              f"{r['n_drift']} | {r['n_caught']} | {100 * r['caught_fraction']:.1f} | "
              f"{r['n_swapped_kept']} | {r['n_stopped_clean']} | {e:.4f} | {tt:.1f} | "
              f"{tr_:.1f} |")
    for surface, n, e, t in exact:
        print(f"| {surface} | none: exact projections of vertex pixels | {n} | {n} | {n} | 0 | 0 | - | - "
              f"| - | - | - | {e:.4f} | - | {t:.1f} |")
    print("\n(tracks that start on the background have no ground truth and are left out of "
          "the error columns; e3d uses the complete on-surface tracks)")


def dense_tracks(P, F, seed):
    """Noise-free tracks of P random points on the face mesh over F frames."""
    v = make_video("face", n_frames=F, seed=seed, size=(480, 640))
    rng = np.random.default_rng(seed)
    tri = rng.integers(0, len(v.triangles), P)
    b = rng.dirichlet(np.ones(3), P)
    world = v.world_points(tri, b)
    pix = v.project(world)                                       # (F, 2, P)
    cam = v.pixel_scale * (v.rotations @ world)
    cam -= cam.mean(axis=2, keepdims=True)
    return v, pix, cam


def scale_table(args):
    import rerun  # noqa: F401  (imported here so that its ~3 s import is not timed below)

    from nrsfm.stages.measurement import centre_rows, factorize, working_scale
    from nrsfm.views.video import save_video_recording
    from nrsfm.stages.rotations import estimate_rotations
    from nrsfm.stages.shape import pseudo_inverse_shapes, solve_shapes

    P, F = args.points, args.frames
    v, pix, cam = dense_tracks(P, F, args.seed)
    W = pix.reshape(2 * F, P)
    rows = []
    (Wc, _), t, m = _measure(lambda: centre_rows(W))
    rows.append(("centre rows", t, m))
    s = working_scale(Wc)
    Wn = Wc / s
    fact, t, m = _measure(lambda: factorize(Wn, 1))
    rows.append(("factorisation: nrsfm.stages.measurement.factorize (+ residual)", t, m))
    _, t, m = _measure(lambda: np.linalg.svd(Wn, full_matrices=False))
    rows.append(("  for comparison: numpy thin SVD of the 2F x P W", t, m))

    def gram_svd():
        G = Wn @ Wn.T                                            # 2F x 2F
        lam, U = np.linalg.eigh(G)
        order = np.argsort(lam)[::-1][:3]
        sv = np.sqrt(np.clip(lam[order], 0, None))
        return U[:, order] * np.sqrt(sv), (U[:, order] / np.sqrt(sv)).T @ Wn
    (M_g, B_g), t, m = _measure(gram_svd)
    rows.append(("factorisation via the 2F x 2F Gram matrix (rank 3)", t, m))
    rel = np.linalg.norm(M_g @ B_g - fact.M_hat @ fact.B_hat) / np.linalg.norm(Wn)
    rot, t, m = _measure(lambda: estimate_rotations(fact.M_hat, 1, seed=0))
    rows.append(("rotation stage (K = 1)", t, m))
    R = rot.rotations
    _, t, m = _measure(lambda: pseudo_inverse_shapes(Wn, R))
    rows.append(("pseudo-inverse shape pinv(R) W", t, m))
    shape = None
    if not args.skip_shape:
        shape, t, m = _measure(lambda: solve_shapes(Wn, R, 1, prior="organic",
                                                    solver=args.shape_solver))
        rows.append((f"shape stage ({args.shape_solver}, {shape.n_iter} iterations)", t, m))
        full, t, m = _measure(lambda: nrsfm.reconstruct(W, 1))
        rows.append(("whole pipeline: nrsfm.reconstruct(W, 1), default settings", t, m))
        e_full = nrsfm.metrics.e3d(full.shapes, cam)
    e = nrsfm.metrics.e3d(shape.shapes if shape is not None
                          else pseudo_inverse_shapes(Wn, R), cam)

    class _R:  # the parts of a Reconstruction the recording reads
        pass
    res = _R()
    res.shapes = (shape.shapes if shape is not None else pseudo_inverse_shapes(Wn, R)) * s
    res.method = "organic" if shape is not None else "pseudo_inverse"
    res.K, res.n_points, res.timings = 1, P, {}
    res.undetermined = np.zeros(P, bool)        # complete tracks: every point seen
    tracks = Tracks(tracks=pix, lost_at=np.full(P, F), fb_error=np.zeros((F, P)),
                    colors=np.full((P, 3), 200, np.uint8), method="dense",
                    image_size=v.frames.shape[1:3])
    with tempfile.TemporaryDirectory() as tmp:
        out = Path(args.rrd) if args.rrd else Path(tmp) / "dense.rrd"
        info, t, m = _measure(lambda: save_video_recording(out, v.frames, tracks, res,
                                                           shapes_gt=cam))
    rows.append((f"recording ({info['points_3d']} of {P} points in 3D, "
                 f"{info['points_2d']} tracks drawn, {F} JPEG frames): "
                 f"{info['bytes'] / 1e6:.1f} MB", t, m))
    print(f"\nTable 2: dense scale, P = {P} points, F = {F} frames, K = 1, noise-free "
          f"(face mesh), W is {2 * F} x {P} = {W.nbytes / 1e6:.0f} MB\n")
    print("| stage | seconds | peak MB (tracemalloc) |")
    print("|---|---|---|")
    for name, t, m in rows:
        print(f"| {name} | {t:.2f} | {m:.0f} |")
    print(f"\nGram-matrix factorisation vs SVD: relative difference of M B {rel:.1e}")
    print(f"e3d ({'organic' if shape is not None else 'pseudo-inverse'}): {e:.4f}")
    if shape is not None:
        print(f"e3d of the whole pipeline (estimated rotations, default solver): {e_full:.4f}")
    print(f"process peak RSS so far: "
          f"{resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1e3:.0f} MB")


def main(argv=None):
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--surfaces", nargs="+", default=["sheet", "face"])
    p.add_argument("--video-frames", type=int, default=100)
    p.add_argument("--step", type=int, default=4, help="dense grid step (pixels)")
    p.add_argument("--swap-px", type=float, default=3.0)
    p.add_argument("--points", type=int, default=30000)
    p.add_argument("--frames", type=int, default=100)
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--skip-video", action="store_true")
    p.add_argument("--skip-scale", action="store_true")
    p.add_argument("--shape-solver", default="bilinear", choices=["bilinear", "admm"],
                   help="shape solver for the per-stage row (default: bilinear)")
    p.add_argument("--skip-shape", action="store_true",
                   help="leave out the shape stage in table 2")
    p.add_argument("--rrd", help="keep table 2's recording at this path")
    args = p.parse_args(argv)
    print(f"threads: OMP_NUM_THREADS={os.environ.get('OMP_NUM_THREADS')}; timings taken on "
          f"a shared 2-core machine")
    if not args.skip_video:
        video_table(args)
    if not args.skip_scale:
        scale_table(args)


if __name__ == "__main__":
    main()

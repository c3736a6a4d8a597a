"""From a video to 3D: ``nrsfm track VIDEO`` and ``nrsfm video VIDEO``.

The reconstruction of tracks with lost points is library code:
:func:`nrsfm.tracks.reconstruct_tracks`; tracking is :mod:`data_tools.video`.
"""

from __future__ import annotations

import time
from pathlib import Path

import numpy as np

from .common import (add_rrd_option, add_shape_solver_option, output_path, positive_int,
                     print_report, rrd_path, say, seed, write_recording)

__all__ = ["add_video_commands", "cmd_track", "cmd_video", "cmd_demo_video"]


def _track(args, check=None):
    """Frames of ``args.video`` and their tracks (printed summary); ``check(frames)`` runs
    before the tracking."""
    from data_tools.video import load_frames, track_dense, track_sparse

    frames = load_frames(args.video, max_frames=args.max_frames)
    if check is not None:
        check(frames)
    t0 = time.perf_counter()
    if args.dense:
        tracks = track_dense(frames, step=args.step, fb_threshold=args.fb_threshold,
                             max_points=args.max_points, detect_every=args.detect_every)
    else:
        tracks = track_sparse(frames, max_points=args.max_points or 2000,
                              fb_threshold=args.fb_threshold,
                              detect_every=args.detect_every)
    say(args)(f"tracked in {time.perf_counter() - t0:.1f} s")
    print(tracks.summary())
    return frames, tracks


def cmd_track(args):
    """``nrsfm track VIDEO -o tracks.npz``."""
    from ..io import atomic_output

    out = args.output or Path(args.video).with_suffix("").as_posix() + "_tracks.npz"
    out = output_path(out, "-o")                      # before the work
    _, tracks = _track(args)
    with atomic_output(out) as tmp:
        tracks.save(tmp)
    print(f"wrote {out} (W: {2 * tracks.n_frames} x {tracks.n_points}, NaN where lost)")
    return 0


def _save_video_rrd(rrd, frames, tracks, vr):
    from ..views.video import save_video_recording

    info = write_recording(rrd, lambda tmp: save_video_recording(tmp, frames, tracks,
                                                                 vr.result, vr.used))
    print(f"wrote Rerun recording {rrd} ({info['bytes'] / 1e6:.1f} MB, "
          f"{info['seconds']:.1f} s; open it with: rerun {rrd})")


def _ground_truth(args):
    """The ``--ground-truth`` file read (before the work), or None."""
    if args.ground_truth is None:
        return None
    from data_tools.video_truth import load_ground_truth

    return load_ground_truth(Path(args.ground_truth).expanduser())


def _check_truth(truth, frames, args):
    """The ground truth must describe the video read: as many frames, the same size."""
    if truth is None:
        return
    if truth.n_frames != len(frames):
        raise ValueError(f"--ground-truth {args.ground_truth} has {truth.n_frames} frames "
                         f"but {len(frames)} were read from {args.video}")
    if tuple(truth.id0.shape) != tuple(frames.shape[1:3]):
        raise ValueError(f"--ground-truth {args.ground_truth} is for images of "
                         f"{truth.id0.shape[1]}x{truth.id0.shape[0]} but {args.video} has "
                         f"{frames.shape[2]}x{frames.shape[1]}")


def _score(truth, tracks, vr):
    """Print and return the errors of the used tracks that started on the surface."""
    from data_tools.video_truth import score_tracks

    sc = score_tracks(truth, tracks, vr)
    print(f"  errors against ground truth ({sc['n_scored']} of the {sc['n_used']} used "
          f"tracks, those that started on the surface): e3d {sc['e3d']:.4f}, e3d (Akhter) "
          f"{sc['e3d_akhter']:.4f}, e_R {sc['e_R']:.4f}")
    return sc


def cmd_video(args):
    """``nrsfm video VIDEO --rrd out.rrd [-o out.npz] [--ground-truth GT.npz]``."""
    from ..io import save_npz
    from ..tracks import reconstruct_tracks

    out = output_path(args.output, "-o") if args.output else None   # before the work
    rrd = rrd_path(args, Path(args.video).stem + ".rrd")
    truth = _ground_truth(args)
    frames, tracks = _track(args, check=lambda fr: _check_truth(truth, fr, args))
    K = 1 if args.K is None else args.K
    vr = reconstruct_tracks(tracks.W, K, method=args.method, seed=args.seed,
                            shape_solver=args.shape_solver,
                            missing="complete" if args.complete_tracks else "auto",
                            progress=not args.quiet)
    how = (f"the {int(vr.used.sum())} tracks seen in 2+ frames (missing data)"
           if vr.missing_data else f"the {vr.n_complete} complete tracks of {vr.n_tracks}")
    print(f"reconstructed {how} with K={K}")
    print_report(vr.result)
    scores = {} if truth is None else _score(truth, tracks, vr)
    if out is not None:
        save_npz(out, W=tracks.W, used=vr.used, rotations=vr.result.rotations,
                 shapes=vr.result.shapes, colors=tracks.colors, lost_at=tracks.lost_at,
                 started_at=tracks.start, undetermined=vr.result.undetermined, K=K,
                 method=np.array(vr.result.method),
                 **{k: np.float64(v) if isinstance(v, float) else np.int64(v)
                    for k, v in scores.items()})
        print(f"wrote {out}")
    if rrd is not None:
        _save_video_rrd(rrd, frames, tracks, vr)
    return 0


def cmd_demo_video(args):
    """``nrsfm demo --video``: write the synthetic video and its ground truth, then run
    ``nrsfm video FRAMES --ground-truth GT.npz`` on them (the command is printed)."""
    from data_tools.synthetic_video import make_video
    from data_tools.video_truth import write_video

    from . import build_parser
    from ..paths import output_dir

    rrd = rrd_path(args, "demo_video.rrd")
    F, size = args.frames or 40, args.size or (240, 320)
    video = make_video(args.surface or "sheet", n_frames=F, size=size, seed=args.seed)
    frames, truth = write_video(video, output_dir("demo_video"))
    argv = ["video", str(frames), "--ground-truth", str(truth), "--method", args.method,
            "--seed", str(args.seed)]
    argv += ["--shape-solver", args.shape_solver] if args.shape_solver else []
    argv += (["--rrd", str(rrd)] if rrd is not None else []) + (
        ["--quiet"] if args.quiet else [])
    print(f"synthetic video: {video.surface}, {F} frames of {size[1]}x{size[0]}, seed "
          f"{args.seed}; wrote {frames}/*.png and {truth}")
    print("running: nrsfm " + " ".join(argv), flush=True)
    return cmd_video(build_parser().parse_args(argv))


def _add_tracking(p):
    p.add_argument("video", help="video file, or folder of images (sorted by name)")
    p.add_argument("--dense", action="store_true",
                   help="dense tracks: optical flow chained over a grid on the textured "
                        "pixels (default: sparse corners + Lucas-Kanade)")
    p.add_argument("--step", type=positive_int, default=4,
                   help="grid spacing in pixels for --dense (default: 4)")
    p.add_argument("--max-points", type=positive_int, default=None,
                   help="at most this many tracks (default: 2000 sparse, all grid points "
                        "dense)")
    p.add_argument("--fb-threshold", type=float, default=1.0,
                   help="forward-backward error (pixels) beyond which a track is lost "
                        "(default: 1.0)")
    p.add_argument("--detect-every", type=seed, default=5, metavar="N",
                   help="start new tracks in textured areas without tracks every N frames "
                        "(NaN before their first frame; 0: only the first frame's; "
                        "default: 5)")
    p.add_argument("--max-frames", type=positive_int, default=None,
                   help="read at most this many frames")
    p.add_argument("--quiet", action="store_true", help="no progress messages")


def add_video_commands(subparsers):
    """Add the ``track`` and ``video`` subcommands to an argparse subparsers object."""
    from ..pipeline import METHODS

    p = subparsers.add_parser(
        "track", help="track points through a video and write them (.npz, NaN where lost)")
    _add_tracking(p)
    p.add_argument("-o", "--output", help="output .npz (default: VIDEO_tracks.npz)")
    p.set_defaults(func=cmd_track)

    p = subparsers.add_parser(
        "video", help="from a video to 3D: track, reconstruct, write a Rerun recording")
    _add_tracking(p)
    p.add_argument("--K", type=positive_int, default=None,
                   help="number of shape bases (default: 1, the paper's dense setting)")
    p.add_argument("--method", choices=sorted(METHODS), default="organic",
                   help="pipeline (default: organic)")
    p.add_argument("--seed", type=seed, default=0, help="random seed (default: 0)")
    add_shape_solver_option(p)
    p.add_argument("--complete-tracks", action="store_true",
                   help="reconstruct only the tracks observed in every frame (default: every "
                        "track seen in 2+ frames, lost and late entries completed as "
                        "missing data)")
    add_rrd_option(p, "VIDEO_NAME.rrd")
    p.add_argument("-o", "--output", help="write tracks, rotations and shapes (.npz)")
    p.add_argument("--ground-truth", metavar="GT.npz",
                   help="score the reconstruction against this ground truth of a synthetic "
                        "video (written by data_tools.write_video or nrsfm demo --video): "
                        "e3d, e3d (Akhter) and e_R over the used tracks that started on "
                        "the surface (also saved with -o)")
    p.set_defaults(func=cmd_video)
    return subparsers

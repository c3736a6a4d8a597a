"""From a video to 3D: ``nrsfm track VIDEO`` and ``nrsfm video VIDEO`` (tracking:
:mod:`data_tools.video`; tracks lost part-way: :func:`nrsfm.tracks.reconstruct_tracks`)."""

from __future__ import annotations

import sys
import time
from pathlib import Path

import numpy as np

from .common import add_camera_options, add_reconstruction_options, camera, output_path
from .common import positive_int, print_report
from .common import rrd_path, seed, write_recording


def _track(args, check=None):
    """Frames of ``args.video`` and their tracks (summary printed); ``check(frames)`` runs
    before the tracking."""
    from data_tools.video import load_frames, track_dense, track_sparse

    frames = load_frames(args.video, max_frames=args.max_frames)
    if check is not None:
        check(frames)
    t0 = time.perf_counter()
    kw = dict(fb_threshold=args.fb_threshold, detect_every=args.detect_every)
    if args.dense:
        tracks = track_dense(frames, step=args.step, max_points=args.max_points, **kw)
    else:
        tracks = track_sparse(frames, max_points=args.max_points or 2000, **kw)
    if not args.quiet:
        print(f"tracked in {time.perf_counter() - t0:.1f} s", file=sys.stderr, flush=True)
    print(tracks.summary())
    return frames, tracks


def cmd_track(args):
    """``nrsfm track VIDEO -o tracks.npz``."""
    from ..io import atomic_output

    out = args.output or Path(args.video).with_suffix("").as_posix() + "_tracks.npz"
    out = output_path(out, "-o")  # before the work
    _, tracks = _track(args)
    with atomic_output(out) as tmp:
        tracks.save(tmp)
    print(f"wrote {out} (W: {2 * tracks.n_frames} x {tracks.n_points}, NaN where lost)")
    return 0


def _check_truth(truth, frames, args):
    """The ground truth must describe the video read: as many frames, the same size."""
    if truth is None:
        return
    gt, video = f"--ground-truth {args.ground_truth}", args.video
    if truth.n_frames != len(frames):
        raise ValueError(
            f"{gt} has {truth.n_frames} frames but {len(frames)} were read from {video}"
        )
    (h, w), (H, W) = truth.id0.shape, frames.shape[1:3]
    if (h, w) != (H, W):
        raise ValueError(f"{gt} is for images of {w}x{h} but {video} has {W}x{H}")


def cmd_video(args):
    """``nrsfm video VIDEO --rrd out.rrd [-o out.npz] [--ground-truth GT.npz]``."""
    from ..io import save_npz
    from ..tracks import reconstruct_tracks

    out = output_path(args.output, "-o") if args.output else None  # before the work
    rrd = rrd_path(args, Path(args.video).stem + ".rrd")
    camera(args, (0, 0))  # the camera options, checked before the tracking
    truth = None
    if args.ground_truth is not None:
        from data_tools.video_truth import load_ground_truth, score_tracks

        truth = load_ground_truth(Path(args.ground_truth).expanduser())
    frames, tracks = _track(args, check=lambda fr: _check_truth(truth, fr, args))
    K = 1 if args.K is None else args.K
    kw = dict(method=args.method, seed=args.seed, shape_solver=args.shape_solver)
    kw.update(intrinsics=camera(args, frames.shape[1:3]))
    missing = "complete" if args.complete_tracks else "auto"
    vr = reconstruct_tracks(tracks.W, K, missing=missing, progress=not args.quiet, **kw)
    if vr.missing_data:
        print(
            f"reconstructed the {int(vr.used.sum())} tracks seen in 2+ frames (missing "
            f"data) with K={K}"
        )
    else:
        print(f"reconstructed the {vr.n_complete} complete tracks of {vr.n_tracks} with K={K}")
    print_report(vr.result)
    scores = {}
    if truth is not None:
        sc = scores = score_tracks(truth, tracks, vr)
        print(
            f"  errors against ground truth ({sc['n_scored']} of the {sc['n_used']} used "
            f"tracks, those that started on the surface): e3d {sc['e3d']:.4f}, e3d (Akhter) "
            f"{sc['e3d_akhter']:.4f}, e_R {sc['e_R']:.4f}"
        )
    if out is not None:
        res = vr.result
        arrays = dict(W=tracks.W, used=vr.used, rotations=res.rotations, shapes=res.shapes)
        arrays.update(colors=tracks.colors, lost_at=tracks.lost_at, started_at=tracks.start)
        arrays.update(undetermined=res.undetermined, K=K, method=np.array(res.method))
        for k, v in scores.items():
            arrays[k] = np.float64(v) if isinstance(v, float) else np.int64(v)
        save_npz(out, **arrays)
        print(f"wrote {out}")
    if rrd is not None:
        from ..views.video import save_video_recording

        def write(tmp):
            return save_video_recording(tmp, frames, tracks, vr.result, vr.used)

        info = write_recording(rrd, write)
        print(
            f"wrote Rerun recording {rrd} ({info['bytes'] / 1e6:.1f} MB, "
            f"{info['seconds']:.1f} s; open it with: rerun {rrd})"
        )
    return 0


def cmd_demo_video(args):
    """``nrsfm demo --video``: write the synthetic video and its ground truth, then run
    ``nrsfm video FRAMES --ground-truth GT.npz`` on them (the command is printed)."""
    from data_tools.synthetic_video import make_video
    from data_tools.video_truth import write_video

    from ..paths import output_dir
    from . import build_parser

    rrd = rrd_path(args, "demo_video.rrd")
    F, size = args.frames or 40, args.size or (240, 320)
    video = make_video(args.surface or "sheet", n_frames=F, size=size, seed=args.seed)
    frames, truth = write_video(video, output_dir("demo_video"))
    argv = ["video", str(frames), "--ground-truth", str(truth), "--method", args.method]
    argv += ["--seed", str(args.seed)]
    argv += ["--shape-solver", args.shape_solver] if args.shape_solver else []
    argv += (["--rrd", str(rrd)] if rrd is not None else []) + ["--quiet"] * args.quiet
    print(
        f"synthetic video: {video.surface}, {F} frames of {size[0]}x{size[1]} (HxW), seed "
        f"{args.seed}; wrote {frames}/*.png and {truth}"
    )
    print("running: nrsfm " + " ".join(argv), flush=True)
    return cmd_video(build_parser().parse_args(argv))


def _add_tracking(p):
    p.add_argument("video", help="video file, or folder of images (sorted by name)")
    text = "dense tracks: optical flow over a grid (default: sparse corners + Lucas-Kanade)"
    p.add_argument("--dense", action="store_true", help=text)
    text = "--dense: grid step in pixels (default: 4)"
    p.add_argument("--step", type=positive_int, default=4, help=text)
    text = "at most this many tracks (default: 2000 sparse, every grid point dense)"
    p.add_argument("--max-points", type=positive_int, help=text)
    text = "forward-backward error (pixels) beyond which a track is lost (default: 1.0)"
    p.add_argument("--fb-threshold", type=float, default=1.0, help=text)
    text = "start tracks where there are none every N frames (0: first frame only; default 5)"
    p.add_argument("--detect-every", type=seed, default=5, metavar="N", help=text)
    p.add_argument("--max-frames", type=positive_int, help="read at most this many frames")
    p.add_argument("--quiet", action="store_true", help="no progress messages")


def add_video_commands(subparsers):
    """Add the ``track`` and ``video`` subcommands."""
    text = "track points through a video and write them (.npz, NaN where lost)"
    p = subparsers.add_parser("track", help=text)
    _add_tracking(p)
    p.add_argument("-o", "--output", help="output .npz (default: VIDEO_tracks.npz)")
    p.set_defaults(func=cmd_track)

    text = "from a video to 3D: track, reconstruct, write a Rerun recording"
    p = subparsers.add_parser("video", help=text)
    _add_tracking(p)
    text = "number of shape bases (default: 1, the paper's dense setting)"
    p.add_argument("--K", type=positive_int, help=text)
    add_camera_options(p)
    add_reconstruction_options(p, "VIDEO_NAME.rrd", quiet=False)
    text = "reconstruct only the tracks seen in every frame (default: every track seen in 2+"
    p.add_argument("--complete-tracks", action="store_true", help=text + " frames)")
    p.add_argument("-o", "--output", help="write tracks, rotations and shapes (.npz)")
    text = "score against this ground truth of a synthetic video (nrsfm demo --video)"
    p.add_argument("--ground-truth", metavar="GT.npz", help=text)
    p.set_defaults(func=cmd_video)

"""From a video to 3D: ``nrsfm track VIDEO`` and ``nrsfm video VIDEO``, and
:func:`reconstruct_tracks` (reconstruction of tracks with lost points).

Register the subcommands with ``add_video_commands(subparsers)``. Bad input raises
``ValueError`` / ``OSError`` with a one-line message (the CLI prints it).
"""

from __future__ import annotations

import sys
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np

__all__ = ["VideoReconstruction", "add_video_commands", "reconstruct_tracks"]


@dataclass
class VideoReconstruction:
    """Result of :func:`reconstruct_tracks`.

    Attributes
    ----------
    result : nrsfm.Reconstruction
        Reconstruction of the tracks in ``used``.
    used : (P,) bool ndarray
        Tracks given to :func:`nrsfm.reconstruct`.
    n_tracks, n_complete : int
        All tracks, and those observed in every frame.
    missing_data : bool
        True when the tracks with NaN (lost) entries were passed to ``reconstruct``
        (it supports missing data); False when only the complete tracks were used.
    """

    result: object
    used: np.ndarray
    n_tracks: int
    n_complete: int
    missing_data: bool


def reconstruct_tracks(W, K=1, *, missing="auto", **kw):
    """Reconstruct tracks that may hold NaN (lost) entries.

    Parameters
    ----------
    W : (2F, P) or (F, 2, P) array_like
        Pixel tracks, NaN where a track is lost.
    K : int
        Number of shape bases (dense input: the paper's K = 1).
    missing : {"auto", "complete"}
        ``auto``: pass every track seen in at least 2 frames, NaN included, to
        :func:`nrsfm.reconstruct` (missing data, completed there); if the observations are
        too sparse for it (a frame with too few tracks), fall back to the complete tracks.
        ``complete``: use the complete tracks only.
    **kw
        Passed to :func:`nrsfm.reconstruct` (``method``, ``seed``, ``progress``, ...).

    Returns
    -------
    VideoReconstruction

    Raises
    ------
    ValueError
        Bad shape, unknown ``missing``, or too few complete tracks for K.
    """
    from .pipeline import reconstruct

    if missing not in ("auto", "complete"):
        raise ValueError(f"missing must be 'auto' or 'complete'; got {missing!r}")
    A = np.asarray(W, float)
    if A.ndim == 3:
        if A.shape[1] != 2:
            raise ValueError(f"tracks must have shape (F, 2, P); got {A.shape}")
        A = A.reshape(2 * A.shape[0], A.shape[2])
    if A.ndim != 2 or A.shape[0] % 2:
        raise ValueError(f"W must have shape (2F, P) or (F, 2, P); got {A.shape}")
    complete = np.isfinite(A).all(axis=0)
    P = A.shape[1]
    if missing == "auto" and not complete.all():
        # a track seen in fewer than 2 frames has no depth to recover: not used
        seen = np.isfinite(A).reshape(A.shape[0] // 2, 2, P).all(axis=1).sum(axis=0) >= 2
        try:
            res = reconstruct(A[:, seen], K, **kw)
            return VideoReconstruction(res, seen, P, int(complete.sum()), True)
        except ValueError as exc:        # e.g. a frame that observes too few tracks
            if not any(w in str(exc) for w in ("NaN", "observe", "too sparse")):
                raise
    n = int(complete.sum())
    if n < max(3, 3 * int(K)):
        raise ValueError(f"only {n} of {P} tracks are complete (observed in every frame); "
                         f"K={K} needs at least {max(3, 3 * int(K))}")
    res = reconstruct(A[:, complete], K, **kw)
    return VideoReconstruction(res, complete, P, n, False)


# --------------------------------------------------------------------------- commands

def _track(args, frames):
    from data_tools.video import track_dense, track_sparse

    if args.dense:
        return track_dense(frames, step=args.step, fb_threshold=args.fb_threshold,
                           max_points=args.max_points)
    return track_sparse(frames, max_points=args.max_points or 2000,
                        fb_threshold=args.fb_threshold)


def _say(args):
    return (lambda m: None) if args.quiet else (lambda m: print(m, file=sys.stderr,
                                                                 flush=True))


def cmd_track(args):
    """``nrsfm track VIDEO -o tracks.npz``."""
    from data_tools.video import load_frames

    from .io import atomic_output, check_output_path

    say = _say(args)
    out = Path(args.output or Path(args.video).with_suffix("").as_posix() + "_tracks.npz")
    check_output_path(out, "-o")                      # before the work
    frames = load_frames(args.video, max_frames=args.max_frames)
    t0 = time.perf_counter()
    tracks = _track(args, frames)
    say(f"tracked in {time.perf_counter() - t0:.1f} s")
    print(tracks.summary())
    with atomic_output(out) as tmp:
        tracks.save(tmp)
    print(f"wrote {out} (W: {2 * tracks.n_frames} x {tracks.n_points}, NaN where lost)")
    return 0


def cmd_video(args):
    """``nrsfm video VIDEO --rrd out.rrd [-o out.npz]``."""
    from data_tools.video import load_frames

    from .io import atomic_output, check_output_path, save_npz
    from .recording_video import save_video_recording

    say = _say(args)
    if args.output:
        check_output_path(args.output, "-o")          # before the work
    if args.rrd:
        if not str(args.rrd).endswith(".rrd"):
            raise ValueError(f"--rrd {args.rrd}: the recording's name must end in .rrd")
        check_output_path(args.rrd, "--rrd")
    frames = load_frames(args.video, max_frames=args.max_frames)
    t0 = time.perf_counter()
    tracks = _track(args, frames)
    say(f"tracked in {time.perf_counter() - t0:.1f} s")
    print(tracks.summary())
    K = 1 if args.K is None else args.K
    vr = reconstruct_tracks(tracks.W, K, method=args.method, seed=args.seed,
                            missing="complete" if args.complete_tracks else "auto",
                            progress=not args.quiet)
    how = ("all tracks (missing data)" if vr.missing_data else
           f"the {vr.n_complete} complete tracks of {vr.n_tracks}")
    print(f"reconstructed {how} with K={K}")
    print(vr.result.summary())
    for flag in vr.result.diagnostics.flags:
        print(f"  WARNING: {flag}")
    if args.output:
        out = Path(args.output)
        save_npz(out, W=tracks.W, used=vr.used, rotations=vr.result.rotations,
                            shapes=vr.result.shapes, colors=tracks.colors,
                            lost_at=tracks.lost_at, K=K, method=np.array(vr.result.method))
        print(f"wrote {out}")
    if args.rrd:
        with atomic_output(args.rrd) as tmp:
            info = save_video_recording(tmp, frames, tracks, vr.result, vr.used)
        info["path"] = args.rrd
        print(f"wrote Rerun recording {info['path']} ({info['bytes'] / 1e6:.1f} MB, "
              f"{info['seconds']:.1f} s; open it with: rerun {info['path']})")
    return 0


def _add_tracking(p):
    p.add_argument("video", help="video file, or folder of images (sorted by name)")
    p.add_argument("--dense", action="store_true",
                   help="dense tracks: optical flow chained over a grid on the textured "
                        "pixels (default: sparse corners + Lucas-Kanade)")
    p.add_argument("--step", type=int, default=4,
                   help="grid spacing in pixels for --dense (default: 4)")
    p.add_argument("--max-points", type=int, default=None,
                   help="at most this many tracks (default: 2000 sparse, all grid points "
                        "dense)")
    p.add_argument("--fb-threshold", type=float, default=1.0,
                   help="forward-backward error (pixels) beyond which a track is lost "
                        "(default: 1.0)")
    p.add_argument("--max-frames", type=int, default=None, help="read at most this many frames")
    p.add_argument("--quiet", action="store_true", help="no progress messages")


def add_video_commands(subparsers):
    """Add the ``track`` and ``video`` subcommands to an argparse subparsers object."""
    from .pipeline import METHODS

    p = subparsers.add_parser(
        "track", help="track points through a video and write them (.npz, NaN where lost)")
    _add_tracking(p)
    p.add_argument("-o", "--output", help="output .npz (default: VIDEO_tracks.npz)")
    p.set_defaults(func=cmd_track)

    p = subparsers.add_parser(
        "video", help="from a video to 3D: track, reconstruct, write a Rerun recording")
    _add_tracking(p)
    p.add_argument("--K", type=int, default=None,
                   help="number of shape bases (default: 1, the paper's dense setting)")
    p.add_argument("--method", choices=sorted(METHODS), default="organic",
                   help="pipeline (default: organic)")
    p.add_argument("--seed", type=int, default=0, help="random seed (default: 0)")
    p.add_argument("--complete-tracks", action="store_true",
                   help="reconstruct only the tracks observed in every frame (default: every "
                        "track seen in 2+ frames, lost entries completed as missing data; "
                        "slower on dense tracks)")
    p.add_argument("--rrd", metavar="PATH", help="write a Rerun recording (.rrd)")
    p.add_argument("-o", "--output", help="write tracks, rotations and shapes (.npz)")
    p.set_defaults(func=cmd_video)
    return subparsers

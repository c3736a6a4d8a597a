"""``nrsfm run INPUT``: reconstruct W read from an ``.npz`` or ``.mat`` file, write the
result (.npz)."""

from __future__ import annotations

import warnings
from pathlib import Path

import numpy as np

from .. import __version__
from ..io import load_npz, save_npz
from ..pipeline import reconstruct
from ..sequence import Sequence
from ..validation import check_K, check_measurements, check_rotations, check_shapes
from ..warnings_catalog import text as warning_text
from .common import UsageError, add_camera_options, add_reconstruction_options, camera
from .common import one_line, output_path, positive_int, print_report, rrd_path, save_rrd

#: Arrays ``nrsfm run`` reads from its input ``.npz``.
INPUT_KEYS = ("W", "K", "shapes", "rotations", "edges")
#: What ``nrsfm track`` writes beside W: read as a tracks file, not warned about
TRACK_KEYS = ("tracks", "lost_at", "started_at", "fb_error", "colors", "image_size", "method")


def _file_K(value):
    """K stored in a file: one integer (an integral float is accepted)."""
    A = np.asarray(value)
    if A.size != 1 or A.ndim > 1:
        raise ValueError(f"K in the input must be one integer; got an array of shape {A.shape}")
    item = A.reshape(()).item()
    if A.dtype.kind in "iu" or (A.dtype.kind == "f" and float(item).is_integer()):
        return int(item)
    raise ValueError(f"K in the input must be an integer; got {item!r}")


def _edges(value, P):
    E = np.asarray(value)
    if E.dtype.kind not in "iu" or E.ndim != 2 or E.shape[1] != 2:
        raise ValueError(
            f"edges must be an integer (E, 2) array; got dtype {E.dtype}, shape {E.shape}"
        )
    if E.size and (E.min() < 0 or E.max() >= P):
        raise ValueError(f"edges must index points 0..{P - 1}; got {E.min()}..{E.max()}")
    return E.astype(int)


def _load_mat(path):
    """The arrays of a ``.mat`` file in ``nrsfm run``'s names (:func:`data_tools.load_mat`:
    a ``W``, or the benchmark's layouts with their ground truth)."""
    from data_tools import load_mat

    if not Path(path).is_file():
        raise FileNotFoundError(f"input file {path} not found")
    seq = load_mat(path)
    arrays = dict(W=seq.W, K=seq.K, shapes=seq.shapes, rotations=seq.rotations, edges=seq.edges)
    return {k: v for k, v in arrays.items() if v is not None}


def _read_input(inp, K_arg, given_rotations):
    """W (2F, P), K and the ground truth (``shapes``, ``rotations``, ``edges``, None when
    absent) of the input file, checked."""
    expected = "an .npz with an array named W, e.g. written by numpy.savez('input.npz', W=W, K=3)"
    data = _load_mat(inp) if inp.suffix.lower() == ".mat" else load_npz(inp, "input", expected)
    if "W" not in data:
        raise ValueError(f"{inp} has no array 'W' (found: {sorted(data) or 'no arrays'})")
    W = check_measurements(data["W"], allow_missing=True)
    F, P = W.shape[0] // 2, W.shape[1]
    used = np.isfinite(W).reshape(F, 2, P).all(axis=1).sum(axis=0) >= 2
    if np.isnan(W).any():  # NaN = not observed: enough observations?
        from ..stages.completion import observed_mask

        W = W[:, used]  # a track seen in fewer than 2 frames has no depth: not used
        observed_mask(W)
    if K_arg is None and "K" not in data:
        raise UsageError("give --K (the input has no array 'K')")
    K = check_K(K_arg if K_arg is not None else _file_K(data["K"]), F, W.shape[1])
    truth = dict.fromkeys(("shapes", "rotations", "edges"))
    if "shapes" in data:
        shapes = check_shapes(data["shapes"], "shapes (ground truth)", n_frames=F, n_points=P)
        truth["shapes"] = shapes[:, :, used]
    if "rotations" in data:
        R = data["rotations"]
        truth["rotations"] = check_rotations(R, "rotations (ground truth)", n_frames=F)
    if "edges" in data:
        E, index = _edges(data["edges"], P), np.cumsum(used) - 1
        truth["edges"] = index[E[used[E].all(axis=1)]]
    if given_rotations and truth["rotations"] is None:
        raise UsageError(f"--given-rotations: {inp} has no array 'rotations'")
    known = INPUT_KEYS + (TRACK_KEYS if "tracks" in data else ())
    ignored = sorted(set(data) - set(known))
    if ignored:
        keys = ", ".join(INPUT_KEYS)
        warnings.warn(warning_text("W-ignored-arrays", inp=inp, ignored=ignored, keys=keys))
    size = data.get("image_size")
    return W, K, truth, used, None if size is None else np.asarray(size).ravel()[:2]


def _output_arrays(result, K, errs):
    """The arrays ``nrsfm run`` writes (documented in the README)."""
    arrays = dict(rotations=result.rotations, shapes=result.shapes, X_init=result.X_init)
    arrays.update(W=result.W, row_means=result.row_means, scale=np.float64(result.scale))
    arrays.update(K=np.int64(K), method=np.array(result.method), version=np.array(__version__))
    if result.shape_stage is not None:
        arrays.update({f"shape_{k}": np.asarray(v) for k, v in result.shape_stage.history.items()})
    if result.rotation_stage is not None:
        rs = result.rotation_stage
        arrays.update(G=rs.G, per_triplet_rotations=rs.per_triplet, kept=rs.kept)
    if result.perspective is not None:
        p = result.perspective
        arrays.update(translations=p.translations, intrinsics=p.intrinsics)
        arrays.update({f"perspective_{k}": np.asarray(v) for k, v in p.history.items()})
    return dict(arrays, **{k: np.float64(v) for k, v in errs.items()})


def cmd_run(args):
    """``nrsfm run INPUT.npz [-o OUT.npz] [--rrd [PATH]]``."""
    inp = Path(args.input).expanduser()
    W, K, truth, used, image_size = _read_input(inp, args.K, args.given_rotations)
    intrinsics = camera(args, image_size)
    if intrinsics is not None and args.given_rotations:
        raise UsageError(
            "--given-rotations and a camera: the perspective refinement "
            "estimates the rotations; give one or the other"
        )
    if not used.all():
        print(
            f"  {int((~used).sum())} of {used.size} tracks seen in fewer than 2 frames not "
            f"used (used_points in the output)"
        )
    # the outputs, checked before the work: neither overwrites the input or the other
    out = args.output if args.output is not None else inp.with_name(inp.stem + "_nrsfm.npz")
    out = output_path(out, "output")
    if out.resolve() == inp.resolve():
        raise UsageError(f"output {out} would overwrite the input")
    rrd = rrd_path(args, out.stem + ".rrd")
    if rrd is not None and rrd.resolve() in (out.resolve(), inp.resolve()):
        raise UsageError(f"--rrd {rrd} would overwrite the input or the output")
    R = truth["rotations"]
    kw = dict(method=args.method, seed=args.seed, shape_solver=args.shape_solver)
    kw.update(rotations=R if args.given_rotations else None, progress=not args.quiet)
    kw.update(intrinsics=intrinsics)
    result = reconstruct(W, K, **kw)
    seq = None
    if truth["shapes"] is not None:
        seq = Sequence(inp.stem, result.W, truth["shapes"], R, K, truth["edges"])
    errs = print_report(result, seq)
    try:
        arrays = _output_arrays(result, K, errs)
        save_npz(out, **(arrays if used.all() else dict(arrays, used_points=used)))
    except OSError as exc:
        raise OSError(f"cannot write the output {out}: {one_line(exc)}") from exc
    print(f"  wrote {out}")
    if rrd is not None:
        save_rrd(result, rrd, seq, image_size)
    return 0


def add_run_command(sub):
    p = sub.add_parser(
        "run",
        help="reconstruct W from an .npz or .mat file and write the result",
        epilog="The output .npz holds rotations (F, 3, 3), shapes (F, 3, P), X_init, W, "
        "row_means, scale, K, method, version, shape_* (shape-stage history), G, "
        "per_triplet_rotations, kept (rotation stage), with a camera translations, intrinsics, "
        "perspective_* (refinement history), and e3d, e3d_akhter, e_R when the input has "
        "ground truth; see docs/cli.md.",
    )
    text = (
        ".npz with W (2F, P) or (F, 2, P) (optional: K, ground truth shapes, rotations, "
        "edges), or .mat with W (and K) or in the MoCap benchmark's layouts"
    )
    p.add_argument("input", help=text)
    p.add_argument("--K", type=positive_int, help="number of shape bases (default: the file's K)")
    text = "output file, written exactly there (default: INPUT_nrsfm.npz)"
    p.add_argument("-o", "--output", metavar="PATH", help=text)
    text = "use the file's rotations instead of estimating them"
    p.add_argument("--given-rotations", action="store_true", help=text)
    add_camera_options(p)
    add_reconstruction_options(p, "OUTPUT_NAME.rrd")
    p.set_defaults(func=cmd_run)

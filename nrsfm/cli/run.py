"""``nrsfm run INPUT.npz``: reconstruct W read from a file, write the result (.npz)."""

from __future__ import annotations

import warnings
from pathlib import Path

import numpy as np

from .. import __version__
from ..validation import check_K, check_measurements, check_rotations, check_shapes
from ..io import load_npz, save_npz
from ..pipeline import reconstruct
from ..sequence import Sequence
from ..warnings_catalog import text
from .common import UsageError, one_line, output_path, positive_int, print_report, rrd_path
from .reconstruct import add_common_options, save_rrd

__all__ = ["add_run_command", "cmd_run", "INPUT_KEYS"]

#: Arrays ``nrsfm run`` reads from its input ``.npz``.
INPUT_KEYS = ("W", "K", "shapes", "rotations", "edges")


#: What ``nrsfm run`` reads, for the messages about an unreadable input.
INPUT_EXPECTED = ("an .npz with an array named W, e.g. written by "
                  "numpy.savez('input.npz', W=W, K=3)")


def _load_npz(path):
    """The arrays of the input ``.npz`` (:func:`nrsfm.io.load_npz`), W among them."""
    path = Path(path).expanduser()
    data = load_npz(path, "input", INPUT_EXPECTED)
    if "W" not in data:
        raise ValueError(f"{path} has no array 'W' (found: {sorted(data) or 'no arrays'})")
    return data


def _numeric(name, A):
    A = np.asarray(A)
    if A.dtype.kind not in "iuf":
        raise ValueError(f"{name} must be a numeric (integer or float) array; got dtype "
                         f"{A.dtype}")
    return A


def _file_K(value):
    """K stored in a file: one integer (an integral float is accepted)."""
    A = np.asarray(value)
    if A.size != 1 or A.ndim > 1:
        raise ValueError(f"K in the input must be one integer; got an array of shape "
                         f"{A.shape}")
    item = A.reshape(()).item()
    if A.dtype.kind in "iu":
        return int(item)
    if A.dtype.kind == "f" and np.isfinite(item) and float(item).is_integer():
        return int(item)
    raise ValueError(f"K in the input must be an integer; got {item!r}")


def _edges(value, P):
    E = np.asarray(value)
    if E.dtype.kind not in "iu" or E.ndim != 2 or E.shape[1] != 2:
        raise ValueError(f"edges must be an integer (E, 2) array; got dtype {E.dtype}, "
                         f"shape {E.shape}")
    if E.size and (E.min() < 0 or E.max() >= P):
        raise ValueError(f"edges must index points 0..{P - 1}; got {E.min()}..{E.max()}")
    return E.astype(int)


def _output_arrays(result, K, errs):
    """The arrays ``nrsfm run`` writes (documented in the README)."""
    arrays = dict(rotations=result.rotations, shapes=result.shapes, X_init=result.X_init,
                  W=result.W, row_means=result.row_means, scale=np.float64(result.scale),
                  K=np.int64(K), method=np.array(result.method),
                  version=np.array(__version__))
    if result.shape_stage is not None:
        for key, val in result.shape_stage.history.items():
            arrays[f"shape_{key}"] = np.asarray(val)
    if result.rotation_stage is not None:
        rs = result.rotation_stage
        arrays.update(G=rs.G, per_triplet_rotations=rs.per_triplet, kept=rs.kept)
    for key, val in errs.items():
        arrays[key] = np.float64(val)
    return arrays


def _read_input(inp, K_arg, given_rotations):
    """W, K and the optional ground truth of the input file, checked.

    Returns
    -------
    W : (2F, P) ndarray
    K : int
    truth : dict
        ``shapes``, ``rotations``, ``edges`` (each None when absent).
    """
    data = _load_npz(inp)
    W = check_measurements(_numeric("W", data["W"]), allow_missing=True)
    if np.isnan(W).any():                 # NaN = not observed: enough observations?
        from ..stages.completion import observed_mask

        observed_mask(W)
    F, P = W.shape[0] // 2, W.shape[1]
    if K_arg is not None:
        K = K_arg
    elif "K" in data:
        K = _file_K(data["K"])
    else:
        raise UsageError("give --K (the input has no array 'K')")
    K = check_K(K, F, P)
    truth = dict(shapes=None, rotations=None, edges=None)
    if "shapes" in data:
        truth["shapes"] = check_shapes(_numeric("shapes", data["shapes"]),
                                       "shapes (ground truth)", n_frames=F, n_points=P)
    if "rotations" in data:
        truth["rotations"] = check_rotations(_numeric("rotations", data["rotations"]),
                                             "rotations (ground truth)", n_frames=F)
    if "edges" in data:
        truth["edges"] = _edges(data["edges"], P)
    if given_rotations and truth["rotations"] is None:
        raise UsageError(f"--given-rotations: {inp} has no array 'rotations'")
    ignored = sorted(set(data) - set(INPUT_KEYS))
    if ignored:
        warnings.warn(text("W-ignored-arrays", inp=inp, ignored=ignored,
                           keys=", ".join(INPUT_KEYS)), stacklevel=1)
    return W, K, truth


def _output_paths(args, inp):
    """The checked output and ``--rrd`` paths; neither may overwrite the input or each
    other."""
    out = (Path(args.output) if args.output is not None
           else inp.with_name(inp.stem + "_nrsfm.npz"))
    out = output_path(out, "output")
    if out.resolve() == inp.resolve():
        raise UsageError(f"output {out} would overwrite the input")
    rrd = rrd_path(args, out.stem + ".rrd")
    if rrd is not None and rrd.resolve() in (out.resolve(), inp.resolve()):
        raise UsageError(f"--rrd {rrd} would overwrite the input or the output")
    return out, rrd


def cmd_run(args):
    """``nrsfm run INPUT.npz [-o OUT.npz] [--rrd [PATH]]``."""
    inp = Path(args.input).expanduser()
    W, K, truth = _read_input(inp, args.K, args.given_rotations)
    out, rrd = _output_paths(args, inp)
    rotations = truth["rotations"]
    result = reconstruct(W, K, method=args.method, seed=args.seed,
                         shape_solver=args.shape_solver,
                         rotations=rotations if args.given_rotations else None,
                         progress=not args.quiet)
    seq = None
    if truth["shapes"] is not None:
        seq = Sequence(name=inp.stem, W=result.W, shapes=truth["shapes"],
                       rotations=rotations, K=K, edges=truth["edges"])
    errs = print_report(result, seq)
    try:
        save_npz(out, **_output_arrays(result, K, errs))
    except OSError as exc:
        raise OSError(f"cannot write the output {out}: {one_line(exc)}") from exc
    print(f"  wrote {out}")
    if rrd is not None:
        save_rrd(result, rrd, seq)
    return 0


def add_run_command(sub):
    p = sub.add_parser(
        "run", help="reconstruct W from an .npz file and write the result",
        epilog="The output .npz holds rotations (F, 3, 3), shapes (F, 3, P), X_init, W, "
               "row_means, scale, K, method, version, shape_* (shape-stage history), G, "
               "per_triplet_rotations, kept (rotation stage) and e3d, e3d_akhter, e_R "
               "when the input has ground truth; see the README. --rrd without PATH "
               "writes out/OUTPUT_NAME.rrd under the current folder (or $NRSFM_OUT).")
    p.add_argument("input", help=".npz with array W (2F, P) or (F, 2, P); optional K, "
                                 "shapes (F, 3, P) and rotations (F, 3, 3) ground truth, edges")
    p.add_argument("--K", type=positive_int,
                   help="number of shape bases (default: the file's K)")
    p.add_argument("-o", "--output", metavar="PATH",
                   help="output file, written exactly there (default: INPUT_nrsfm.npz)")
    p.add_argument("--given-rotations", action="store_true",
                   help="use the file's rotations instead of estimating them")
    add_common_options(p, "OUTPUT_NAME.rrd")
    p.set_defaults(func=cmd_run)

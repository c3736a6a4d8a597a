"""The MoCap benchmark table: every method of `nrsfm.reconstruct` on the 8 sequences.

Usage::

    NRSFM_DATA=/path/to/data python benchmarks/mocap_benchmark.py \
        [--sequences drink pickup ...] [--methods organic bmm] [--dai-k]

Prints, per sequence, e3d (the paper's metric), e3d under Akhter's metric, e_R where ground
truth rotations exist, and the run time, with the published figures beside ours (read from
``nrsfm/data/published.json`` through :mod:`nrsfm.published`, never typed in here; their
sources are in that file). ``--dai-k`` also runs BMM
with Dai et al.'s own K and the Akhter metric, to compare with Dai's code run as a peer.
One BLAS thread (the library sets it).
"""

from __future__ import annotations

import argparse
import time

import data_tools as dt
import nrsfm
from nrsfm.published import published


def run(seq, method, K, seed):
    t0 = time.perf_counter()
    res = nrsfm.reconstruct(seq.W, K, method=method, seed=seed)
    dt_s = time.perf_counter() - t0
    err = res.errors(seq.shapes, seq.rotations if seq.name in ("drink", "pickup", "yoga",
                                                               "stretch") else None)
    return res, err, dt_s


def fmt(x, nd=4):
    return "-" if x is None else f"{x:.{nd}f}"


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--data",
                    help="the folder that holds mocap/, or mocap/ itself (default: $NRSFM_DATA)")
    ap.add_argument("--sequences", nargs="+", default=list(dt.MOCAP_NAMES))
    ap.add_argument("--methods", nargs="+", default=["organic", "bmm"],
                    choices=sorted(nrsfm.METHODS))
    ap.add_argument("--no-published", action="store_true",
                    help="do not print the published figures beside ours")
    ap.add_argument("--dai-k", action="store_true",
                    help="also run BMM with Dai's K under the Akhter metric")
    ap.add_argument("--seed", type=int, default=0)
    args = ap.parse_args(argv)
    mocap = args.data
    paper = None if args.no_published else published()

    rows = []
    for name in args.sequences:
        seq = dt.load_mocap(name, mocap)
        for method in args.methods:
            res, err, secs = run(seq, method, seq.K, args.seed)
            rows.append((name, method, seq.K, err, secs))
            print(f"{name:8s} {method:8s} K={seq.K:2d} e3d {fmt(err['e3d'])} "
                  f"akhter {fmt(err['e3d_akhter'])} e_R {fmt(err.get('e_R'))} "
                  f"{secs:6.2f} s", flush=True)

    print()
    head = f"{'sequence':8s} {'method':8s} {'K':>3s} {'e3d':>7s} {'e_R':>7s} {'time s':>7s}"
    if paper:
        head += f" {'paper':>7s} {'ratio':>6s} {'paperBMM':>8s} {'paper e_R':>9s}"
    print(head)
    for name, method, K, err, secs in rows:
        line = (f"{name:8s} {method:8s} {K:3d} {fmt(err['e3d']):>7s} "
                f"{fmt(err.get('e_R')):>7s} {secs:7.2f}")
        if paper:
            key = {"organic": "ours", "bmm": "BMM", "wnn": "R-BMM"}.get(method)
            ref = paper["mocap_e3d"].get(key, {}).get(name) if key else None
            ratio = err["e3d"] / ref if ref else None
            er = paper["mocap_rotation_error"].get(key, {}).get(name) if key else None
            line += (f" {fmt(ref):>7s} {fmt(ratio, 2):>6s} "
                     f"{fmt(paper['mocap_e3d']['BMM'][name]):>8s} {fmt(er):>9s}")
        print(line)

    if args.dai_k:
        print("\nBMM with Dai's K, Akhter metric (compare: Dai's code run as a peer)")
        print(f"{'sequence':8s} {'K':>3s} {'akhter':>7s} {'e_R':>7s} {'time s':>7s}"
              + (f" {'peer':>7s} {'ratio':>6s} {'peer e_R':>8s}" if paper else ""))
        for name in args.sequences:
            seq = dt.load_mocap(name, mocap)
            K = dt.DAI_K[name]
            res, err, secs = run(seq, "bmm", K, args.seed)
            line = f"{name:8s} {K:3d} {fmt(err['e3d_akhter']):>7s} {fmt(err.get('e_R')):>7s} {secs:7.2f}"
            if paper:
                peer = paper["peer_bmm_octave"]
                ref = peer["e3d_akhter"].get(name)
                line += (f" {fmt(ref):>7s} {fmt(err['e3d_akhter'] / ref, 2):>6s} "
                         f"{fmt(peer['e_R'].get(name)):>8s}")
            print(line, flush=True)


if __name__ == "__main__":
    main()

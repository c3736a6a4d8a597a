"""Warnings that mean something (issue 23, acceptance 2): the default pipeline on MoCap
(and external) ground-truth shapes re-projected by new camera paths
(``data_tools.validation_set``), with the shape stage alone on the exact rotations beside it.

Per row: e3d and e_R of ``nrsfm.reconstruct(W, K)``, e3d with the exact rotations
(``rotations=R``, default shape solver), the ``depth_amplification`` signal (the flag of
``W-depth-undetermined``), the flags raised and the notes. ``bad``: e3d above 0.1 through
the pipeline or with the exact rotations (a warning expected); ``good``: e3d below 0.03
(no warning expected); ``ok`` says whether the row met its expectation ("-" for rows that
are neither). The exact-rotation column is left out
("-") on the original paths of sequences without ground-truth cameras (dance, face,
walking, shark). Names of ``data_tools.EXTERNAL`` (``back``) are read with
``data_tools.load_external`` from ``--external-data``.

Example::

    OPENBLAS_NUM_THREADS=1 python benchmarks/rotation_study_warnings.py --data DATA \\
        --sequences pickup stretch drink back --external-data DATA/external --noise 0 0.02
"""

from __future__ import annotations

import argparse
import os
import sys
import warnings

sys.path.insert(0, os.path.dirname(os.path.dirname(os.path.abspath(__file__))))

PATHS = ["original", "smooth62", "smooth145", "smooth180", "fast", "random"]
GOOD_E3D = 0.03
BAD_E3D = 0.1
#: MoCap sequences whose original path has no ground-truth cameras
NO_CAMERAS = ("dance", "face", "walking", "shark")


def flag_names(diagnostics):
    """Short names of the flags raised (the signal each one is about)."""
    keys = {"W-depth-undetermined": "depth", "W-rank-deficient": "rank",
            "W-triplet-bad-minimum": "cost", "W-triplet-unconfirmed": "hits",
            "W-samples-disagree": "filter", "W-camera-jumps": "signs",
            "W-static-camera": "spread", "W-transposed": "transposed",
            "W-ill-conditioned": "condition"}      # ids of docs/warnings.md
    return sorted({keys.get(f.split(":", 1)[0], "other") for f in diagnostics.flags})


def note_names(diagnostics):
    """The ids of the notes (``N-...``) without their prefix."""
    return sorted({n.split(":", 1)[0][2:] for n in diagnostics.notes})


def run_row(seq):
    """One row's figures (a dict)."""
    import nrsfm

    x = seq.extra
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        res = nrsfm.reconstruct(seq.W, seq.K)
        cameras = not (x["path"] == "original" and x["source"] in NO_CAMERAS)
        exact = nrsfm.reconstruct(seq.W, seq.K, rotations=seq.rotations) if cameras else None
    sig = res.diagnostics.signals
    return dict(sequence=x["source"], path=x["path"], turn=x["turn"], noise=x["noise"],
                e3d=nrsfm.e3d(res.shapes, seq.shapes),
                e_R=nrsfm.rotation_error(res.rotations, seq.rotations) if cameras else None,
                e3d_exact=nrsfm.e3d(exact.shapes, seq.shapes) if cameras else None,
                amp=sig.get("depth_amplification", float("nan")),
                flags=flag_names(res.diagnostics), notes=note_names(res.diagnostics))


def verdicts(rows):
    """Add ``expect`` (good / bad / -) and ``ok`` to every row."""
    for r in rows:
        if r["e3d"] > BAD_E3D or (r["e3d_exact"] or 0.0) > BAD_E3D:
            r["expect"], r["ok"] = "bad", bool(r["flags"])
        elif r["e3d"] < GOOD_E3D:
            r["expect"], r["ok"] = "good", not r["flags"]
        else:
            r["expect"], r["ok"] = "-", None
    return rows


def _num(v, fmt):
    return "-" if v is None else format(v, fmt)


def main(argv=None):
    import data_tools

    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--data", default=os.environ.get("NRSFM_DATA"),
                    help="the folder that holds mocap/, or mocap/ itself (default: $NRSFM_DATA)")
    ap.add_argument("--sequences", nargs="+", default=["pickup", "stretch", "drink"])
    ap.add_argument("--paths", nargs="+", default=PATHS)
    ap.add_argument("--noise", nargs="+", type=float, default=[0.0, 0.02])
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--external-data", default=None,
                    help="folder of the external sets (for back; default: data_tools' rule)")
    a = ap.parse_args(argv)
    folder = a.data

    def load(name):
        if name in data_tools.EXTERNAL:
            return data_tools.load_external(name, a.external_data)
        return data_tools.load_mocap(name, folder)

    spec = [(q, p, z) for q in a.sequences for p in a.paths for z in a.noise]
    rows = []
    for seq in data_tools.validation_set(spec, load, seed=a.seed):
        rows.append(run_row(seq))
        r = rows[-1]
        print(f"{seq.name}: e3d {r['e3d']:.4f} amplification {r['amp']:.3g} flags "
              f"{r['flags']}", file=sys.stderr, flush=True)
    print("| sequence | path | turn | noise | e3d | e_R | e3d exact R | depth amplification | "
          "flags | notes | expected | ok |")
    print("|---|---|---|---|---|---|---|---|---|---|---|---|")
    for r in verdicts(rows):
        ok = "-" if r["ok"] is None else ("yes" if r["ok"] else "NO")
        print(f"| {r['sequence']} | {r['path']} | {r['turn']:.0f} | {r['noise']:g} | "
              f"{r['e3d']:.4f} | {_num(r['e_R'], '.3f')} | {_num(r['e3d_exact'], '.4f')} | "
              f"{r['amp']:.3g} | {', '.join(r['flags']) or '-'} | "
              f"{', '.join(r['notes']) or '-'} | {r['expect']} | {ok} |")
    judged = [r for r in rows if r["ok"] is not None]
    print(f"\n{sum(r['ok'] for r in judged)} of {len(judged)} judged rows as expected "
          f"(bad rows that warn: {sum(r['ok'] for r in judged if r['expect'] == 'bad')} of "
          f"{sum(r['expect'] == 'bad' for r in judged)}; good rows without a warning: "
          f"{sum(r['ok'] for r in judged if r['expect'] == 'good')} of "
          f"{sum(r['expect'] == 'good' for r in judged)})")


if __name__ == "__main__":
    main()

"""Render the documentation figures (PNG, matplotlib Agg) from the project's own code.

    python tools/render_figures.py --out docs/figures [--mocap pickup] [--no-mocap]

On the built-in synthetic sequence (``data_tools.default_sequence()``): shapes beside ground
truth, camera trajectory, shape-stage history (organic vs weighted vs nuclear
norm), singular values. With ``NRSFM_DATA`` set, the same for one MoCap sequence.

The full organic pipeline runs (estimated rotations).
"""

from __future__ import annotations

import argparse
import os
import sys
import time
from pathlib import Path

for _v in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_v, "1")

import matplotlib  # noqa: E402

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

import data_tools  # noqa: E402
import nrsfm  # noqa: E402
from nrsfm.views import figures, recording_content  # noqa: E402


def render(seq, out, tag):
    t0 = time.perf_counter()
    res = nrsfm.reconstruct(seq.W, seq.K, method="organic")
    print(
        f"  {seq.name}: organic (estimated rotations) {time.perf_counter() - t0:.1f}s, "
        f"errors {res.errors(seq.shapes, seq.rotations)}"
    )
    content = recording_content(res, seq)
    written = []

    def save(fig, name):
        path = out / f"{tag}_{name}.png"
        fig.savefig(path, dpi=110)
        plt.close(fig)
        written.append(path)

    save(
        figures.shapes_figure(
            res,
            seq,
            content=content,
            title=f"{seq.name}: organic reconstruction (estimated "
            f"rotations) vs ground truth, e3d {content.errors.get('e3d', float('nan')):.3g}",
        ),
        "shapes",
    )
    if content.cameras_gt is not None or res.rotation_stage is not None:
        save(
            figures.cameras_figure(
                res,
                seq,
                content=content,
                title=f"{seq.name}: camera trajectory (estimated rotations)",
            ),
            "cameras",
        )
    runs, labels = [res], ["organic (first singular value free)"]
    for method, lab in (("wnn", "weighted nuclear norm"), ("bmm", "nuclear norm (BMM)")):
        if seq.rotations is not None:  # same rotations for all three: compare priors
            runs.append(nrsfm.reconstruct(seq.W, seq.K, method=method, rotations=res.rotations))
            labels.append(lab)
    errs = [r.errors(seq.shapes)["e3d"] for r in runs]
    save(
        figures.admm_figure(
            runs,
            [f"{lab}: e3d {e:.3g}" for lab, e in zip(labels, errs)],
            title=f"{seq.name}: shape-stage history (default solver), same rotations",
        ),
        "admm",
    )
    sv = content.singular_values
    save(
        figures.singular_values_figure(
            [sv["W"], sv["X_init"]],
            ["W / scale", "X_init# / scale"],
            mark=3 * seq.K,
            title=f"{seq.name}: singular values (3K = {3 * seq.K})",
        ),
        "singular_values",
    )
    return written


def main(argv=None):
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--out", default="docs/figures", help="output folder (default docs/figures)")
    p.add_argument("--mocap", default="pickup", help="MoCap sequence when NRSFM_DATA is set")
    p.add_argument("--no-mocap", action="store_true", help="synthetic figures only")
    args = p.parse_args(argv)
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    written = render(data_tools.default_sequence(), out, "synthetic")
    if not args.no_mocap and os.environ.get("NRSFM_DATA"):
        written += render(data_tools.load_mocap(args.mocap), out, f"mocap_{args.mocap}")
    elif not args.no_mocap:
        print("NRSFM_DATA not set: MoCap figures skipped")
    for w in written:
        print(f"wrote {w}")
    return 0


if __name__ == "__main__":
    sys.exit(main())

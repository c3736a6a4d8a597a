# %% [markdown]
# # 06 · The MoCap benchmark beside the paper's tables
#
# The 8-sequence MoCap benchmark (Akhter et al.: drink, pickup, yoga, stretch, dance;
# Torresani et al.: face, walking, shark), with the paper's $K$ per sequence
# (`data_tools.MOCAP_K`, Table 2). Metrics (Sec. 4, `nrsfm.metrics`): `e3d` (per-frame
# similarity Procrustes, relative Frobenius error) and `e_R` (Table 5, one global
# alignment, spectral norm per frame). The published figures come with the package
# (`nrsfm.published`, a data file that names its source for every table).
#
# **What runs.** Every sequence, in this order, unless the time budget
# (`NRSFM_BENCH_BUDGET` seconds, default 240) is spent: then the remaining ones are listed
# as *not run* in the table, never dropped silently. Up to four runs per sequence:
#
# * `organic`: the full pipeline, `nrsfm.reconstruct(W, K)` (needs `nrsfm.stages.rotations`);
# * `bmm`: the baseline of Dai et al. in the same code (`method="bmm"`: best single
#   triplet, plain nuclear norm), beside the paper's BMM column (note: the paper quotes
#   BMM's published figures, which use Akhter's metric, `nrsfm.e3d_akhter`, not `e3d`);
# * `organic | GT R`: the shape stage alone on the ground-truth rotations (Akhter sequences,
#   which have them): the check that the shape stage (default solver) is right, free of
#   rotation errors;
# * `PI | GT R`: the pseudo-inverse shape on the ground-truth rotations, which reproduces
#   the paper's "Ours-PI" row (Table 1) exactly.
#
# Face, walking and shark have no camera ground truth (their motion is inside the shape),
# so only the full pipeline can run on them. The benchmark data is read from
# `$NRSFM_DATA/mocap` (CI sets it; a relative path is taken from the folder Jupyter or the
# shell was started in, `nrsfm.paths.data_dir`); without it this notebook says so and stops
# early.

# %%
import os

for _v in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_v, "1")

import time
import warnings
from pathlib import Path

import matplotlib.pyplot as plt
import numpy as np

import data_tools
import nrsfm
from nrsfm import paths
from nrsfm.published import published_value
from nrsfm.views import output_path, save_recording, show_recording, shown_path

MOCAP = paths.data_dir() / "mocap" if os.environ.get("NRSFM_DATA") else Path("/nonexistent")
HAVE_DATA = MOCAP.is_dir()
BUDGET = float(os.environ.get("NRSFM_BENCH_BUDGET", 240))
print(f"benchmark data: {HAVE_DATA}; budget {BUDGET:.0f} s")
if not HAVE_DATA:
    print(f"NRSFM_DATA is not set (or {MOCAP} does not exist): nothing to run here.")
    # CI must run the benchmark (as tests/conftest.py requires for the data tests)
    assert not os.environ.get("CI"), "CI must set NRSFM_DATA to the folder holding mocap/"

# %%
PAPER_E3D = published_value("mocap_e3d", "ours")
PAPER_BMM = published_value("mocap_e3d", "BMM")
PAPER_PI = published_value("mocap_pseudo_inverse_e3d", "ours-PI")
PAPER_ER = published_value("mocap_rotation_error", "ours")
PAPER_DAI_R = published_value("mocap_e3d_rotation_ablation", "ours_shape_with_dai_rotation")
print("paper e3d (ours):", PAPER_E3D)

# %% [markdown]
# ## Run


# %%
def run_sequence(seq):
    """The organic and bmm pipelines, and the shape stage on the true cameras: a row."""
    row = dict(F=seq.n_frames, P=seq.n_points, K=seq.K, status="run")
    t0 = time.perf_counter()
    res = nrsfm.reconstruct(seq.W, seq.K)
    row["t_full"] = time.perf_counter() - t0
    err = res.errors(seq.shapes, seq.rotations)
    row["e3d"], row["e_R"] = err["e3d"], err.get("e_R")
    t0 = time.perf_counter()
    row["e3d_bmm"] = nrsfm.reconstruct(seq.W, seq.K, method="bmm").errors(seq.shapes)["e3d"]
    row["t_full"] += time.perf_counter() - t0
    if seq.rotations is not None:
        t0 = time.perf_counter()
        res_gt = nrsfm.reconstruct(seq.W, seq.K, rotations=seq.rotations)
        row["t_gt"] = time.perf_counter() - t0
        row["e3d_gtR"] = res_gt.errors(seq.shapes)["e3d"]
        row["pi_gtR"] = nrsfm.reconstruct(
            seq.W, seq.K, method="pseudo_inverse", rotations=seq.rotations
        ).errors(seq.shapes)["e3d"]
    return row, res


rows = {}
results = {}
t_start = time.perf_counter()
for name in data_tools.MOCAP_NAMES if HAVE_DATA else ():
    spent = time.perf_counter() - t_start
    if spent > BUDGET:
        rows[name] = dict(status=f"not run: budget {BUDGET:.0f} s spent")
        continue
    seq = data_tools.load_mocap(name, data_dir=MOCAP)
    with warnings.catch_warnings(record=True) as log:  # expected: listed below the table
        warnings.simplefilter("always")
        rows[name], results[name] = run_sequence(seq)
    rows[name]["warned"] = sorted({str(w.message).split(": ")[1] for w in log})
    print(f"{name:8s} done at {time.perf_counter() - t_start:6.1f} s")
total = time.perf_counter() - t_start


def fmt(v, spec=".4f"):
    return "-" if v is None else format(v, spec)


header = (
    f"{'seq':8s} {'F':>5s} {'K':>3s} | {'e3d':>7s} {'paper':>7s} | {'bmm':>7s} "
    f"{'paper':>7s} | {'e_R':>7s} "
    f"{'paper':>7s} | {'e3d|GT R':>8s} {'PI|GT R':>8s} {'paper PI':>8s} | {'s':>5s}  status"
)
print(header)
print("-" * len(header))
for name, r in rows.items():
    secs = (r.get("t_full") or 0) + (r.get("t_gt") or 0)
    print(
        f"{name:8s} {r.get('F', 0):5d} {r.get('K', 0):3d} | {fmt(r.get('e3d')):>7s} "
        f"{fmt(PAPER_E3D.get(name)):>7s} | {fmt(r.get('e3d_bmm')):>7s} "
        f"{fmt(PAPER_BMM.get(name)):>7s} | {fmt(r.get('e_R')):>7s} "
        f"{fmt(PAPER_ER.get(name)):>7s} | {fmt(r.get('e3d_gtR')):>8s} "
        f"{fmt(r.get('pi_gtR')):>8s} {fmt(PAPER_PI.get(name)):>8s} | {secs:5.1f}  "
        f"{r['status']}"
    )
print(f"total {total:.1f} s")
for name, r in rows.items():
    if r.get("warned"):
        print(f"{name:8s} warned: {', '.join(r['warned'])}")

# %% [markdown]
# The runs listed as warned say `W-depth-undetermined`: their cameras leave the depth of
# the moving parts open (face's camera does not move at all, its motion is inside the
# shape), so the prior, not the images, sets that depth. The table's errors are still the
# paper's measure; the warning says why W alone cannot vouch for them.

# %% [markdown]
# ## Checks
#
# * `PI | GT R` must reproduce the paper's "Ours-PI" row to its printed precision on drink,
#   pickup, yoga and stretch (this is how the `e3d` definition is confirmed):
#   tolerance 5e-4. (Dance is reported in the table above, not asserted: the paper's
#   rotations there are estimated, ours are the fixed ground-truth camera.)
# * `organic | GT R` must stay within 20 % of `REF_GT_R` below: what this code's default
#   shape stage gave on ground-truth rotations when the reference was last set (the
#   "ground-truth rotation" row of `docs/benchmark/rotation_ablation.md`). A regression
#   check; the cell prints each measured value beside its reference.
# * The full pipeline is compared with the paper's "Ours" column: it must be
#   within 2x of the published figure on the four Akhter sequences the paper's method
#   solves well (drink, pickup, yoga, stretch); the others are reported, not asserted.

# %%
REF_GT_R = {"drink": 0.0074, "pickup": 0.0131, "yoga": 0.0129, "stretch": 0.0152}
for name, r in rows.items():
    if r.get("e3d_gtR") is not None and name in REF_GT_R:
        print(
            f"{name:8s} organic | GT R {r['e3d_gtR']:.4f}, reference {REF_GT_R[name]:.4f} "
            f"({100 * (r['e3d_gtR'] / REF_GT_R[name] - 1):+.1f} %)"
        )
for name, r in rows.items():
    if r.get("pi_gtR") is not None and name in ("drink", "pickup", "yoga", "stretch"):
        assert abs(r["pi_gtR"] - PAPER_PI[name]) < 5e-4, (name, r["pi_gtR"], PAPER_PI[name])
    if r.get("e3d_gtR") is not None and name in REF_GT_R:
        assert abs(r["e3d_gtR"] - REF_GT_R[name]) < 0.2 * REF_GT_R[name], (name, r["e3d_gtR"])
    if r.get("e3d") is not None and name in ("drink", "pickup", "yoga", "stretch"):
        assert r["e3d"] < 2 * PAPER_E3D[name], (name, r["e3d"], PAPER_E3D[name])
not_run = [n for n, r in rows.items() if r["status"] != "run"]
print("not run:", not_run or "none")

# %% [markdown]
# ## Beside the paper

# %%
if rows:
    names = [n for n in rows if rows[n]["status"] == "run"]
    x = np.arange(len(names))
    fig, ax = plt.subplots(figsize=(9, 3.5))
    series = [
        ("paper: Ours", [PAPER_E3D.get(n) for n in names]),
        ("paper: Ours shape + Dai R", [PAPER_DAI_R.get(n) for n in names]),
        ("paper: BMM", [PAPER_BMM.get(n) for n in names]),
        ("this code: organic", [rows[n].get("e3d") for n in names]),
        ("this code: bmm", [rows[n].get("e3d_bmm") for n in names]),
        ("this code: organic | GT R", [rows[n].get("e3d_gtR") for n in names]),
    ]
    w = 0.8 / len(series)
    for i, (lab, vals) in enumerate(series):
        v = np.array([np.nan if a is None else a for a in vals], float)
        if np.isfinite(v).any():
            ax.bar(x + (i - len(series) / 2 + 0.5) * w, v, w, label=lab)
    ax.set_yscale("log")
    ax.set_xticks(x, names)
    ax.set_ylabel("e3d")
    ax.legend(fontsize=8)
    ax.grid(alpha=0.3, axis="y")
    plt.show()

# %% [markdown]
# ## Recording of the largest sequence run (drink: 1102 frames)
#
# Shapes and skeletons per frame against the ground truth, cameras, rotation samples (full
# pipeline), the shape stage's history, report.

# %%
if results:
    name = max(results, key=lambda n: results[n].n_frames)
    t0 = time.perf_counter()
    rrd = save_recording(
        results[name],
        output_path(f"06_mocap_{name}.rrd"),
        data_tools.load_mocap(name, data_dir=MOCAP),
    )
    print(
        f"wrote {shown_path(rrd)} ({rrd.stat().st_size / 1e6:.2f} MB, "
        f"{time.perf_counter() - t0:.1f} s)"
    )
    show_recording(rrd)

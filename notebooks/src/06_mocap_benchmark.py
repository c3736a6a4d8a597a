# %% [markdown]
# # 06 · The MoCap benchmark beside the paper's tables
#
# **What you will learn**
#
# - the eight motion-capture sequences the paper evaluates on, and the K it uses for each;
# - how the paper's 3D error e3d is computed (a similarity alignment per frame, then a
#   relative error), built by hand and checked against `nrsfm.e3d`;
# - how the whole method compares with the paper's published figures, and two checks that
#   separate the stages: the shape stage on the true cameras, and the pseudo-inverse shape
#   that must reproduce the paper's Table 1 exactly.
#
# **Prerequisites**: lessons 00-05 (the method's stages); the MoCap data in `NRSFM_DATA`
# (the README says where it comes from). Without the data this lesson says so and stops.
#
# **Paper**: Sec. 4; Table 1 (pseudo-inverse shapes), Table 2 (MoCap e3d, the K per
# sequence), Table 5 (rotation error e_R).
#
# ## The idea
#
# Motion capture gives the true 3D positions of markers on a moving body. Projecting them
# with known cameras gives the 2D tracks W, so a reconstruction from W can be compared with
# the truth. Two things are free in that comparison, and the error must ignore them: a
# reconstruction from one camera cannot know the object's size and its place, and it may
# come out mirrored in depth. So each frame is aligned to the truth first, then the error is
# measured. The picture: pickup reconstructed and drawn over its ground truth.

# %%
import os

for _v in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_v, "1")

import time
import warnings

import matplotlib.pyplot as plt
import numpy as np

import data_tools
import nrsfm
from nrsfm import paths
from nrsfm.published import published_value
from nrsfm.views import figures, output_path, save_recording, show_recording, shown_path
from nrsfm.warnings_catalog import ids_in

MOCAP = paths.data_dir() / "mocap" if os.environ.get("NRSFM_DATA") else None
HAVE_DATA = MOCAP is not None and (MOCAP / "pickup.mat").is_file()
print("MoCap data:", "found" if HAVE_DATA else "not found: set NRSFM_DATA (the rest is skipped)")

# %%
if HAVE_DATA:
    pickup = data_tools.load_mocap("pickup", data_dir=MOCAP)
    result = nrsfm.reconstruct(pickup.W, pickup.K)
    print(f"pickup: F = {pickup.n_frames} frames, P = {pickup.n_points} markers, K = {pickup.K}")
    figures.shapes_figure(result, pickup, title="pickup: reconstruction over the ground truth")
    plt.show()

# %% [markdown]
# Four frames of pickup: the reconstruction's points sit inside the rings of the true
# markers, after the alignment described next.
#
# ## The error measure, by hand
#
# For each frame, centre both point sets, find the scale s, rotation (or reflection) Q and
# the translation that bring the estimate $\hat{\mathbf X}_f$ closest to the truth
# $\mathbf X_f$ (an orthogonal Procrustes problem, solved by one SVD), and take the relative
# error $\|\mathbf X_f-s\mathbf Q\hat{\mathbf X}_f\|_F/\|\mathbf X_f\|_F$ (both centred).
# e3d is its mean over the frames.


# %%
def frame_error(X_est, X_true):
    """Relative error of one frame (3, P) after the best similarity (reflections allowed)."""
    A = X_est - X_est.mean(axis=1, keepdims=True)
    B = X_true - X_true.mean(axis=1, keepdims=True)
    U, sv, Vt = np.linalg.svd(B @ A.T)  # Q = U Vt maximises trace(Q A B'): Procrustes
    Q = U @ Vt
    s = sv.sum() / np.sum(A**2)  # the best scale for that Q
    return np.linalg.norm(B - s * Q @ A) / np.linalg.norm(B)


if HAVE_DATA:
    by_hand = np.mean([frame_error(a, b) for a, b in zip(result.shapes, pickup.shapes)])
    print(f"e3d by hand {by_hand:.6f}, nrsfm.e3d {nrsfm.e3d(result.shapes, pickup.shapes):.6f}")

# %% [markdown]
# The two agree to the printed digits: `nrsfm.e3d` is this computation (it also rescales
# both inputs by a power of two first, which changes nothing but the rounding). The paper's
# rotation error e_R (Table 5) aligns all the cameras at once and measures each frame's
# rotation difference; `result.errors` gives both.
#
# ## All eight sequences
#
# For each sequence: the whole method; and, where the true cameras are known (the five
# sequences of Akhter et al.), the shape stage alone on them and the pseudo-inverse shape
# on them. The first isolates the shape stage from the rotations; the second has no free
# choice at all, so it must match the paper's Table 1.


# %%
def run_sequence(seq):
    """e3d (and e_R) of the method; on the true cameras, of the shape stage and of the
    pseudo-inverse shape."""
    res = nrsfm.reconstruct(seq.W, seq.K)
    row = dict(K=seq.K, F=seq.n_frames, **res.errors(seq.shapes, seq.rotations))
    if seq.rotations is not None:
        R = seq.rotations
        row["shape_only"] = nrsfm.reconstruct(seq.W, seq.K, rotations=R).errors(seq.shapes)["e3d"]
        pi = nrsfm.reconstruct(seq.W, seq.K, method="pseudo_inverse", rotations=R)
        row["pseudo_inverse"] = pi.errors(seq.shapes)["e3d"]
    return row, res


# %%
rows, results, t0 = {}, {}, time.perf_counter()
for name in data_tools.MOCAP_NAMES if HAVE_DATA else ():
    seq = data_tools.load_mocap(name, data_dir=MOCAP)
    with warnings.catch_warnings(record=True) as log:  # expected: listed and explained below
        warnings.simplefilter("always")
        rows[name], results[name] = run_sequence(seq)
    rows[name]["warned"] = sorted({i for w in log for i in ids_in(w.message)})
print(f"{len(rows)} sequences in {time.perf_counter() - t0:.0f} s")

# %% [markdown]
# Each sequence takes a fraction of a second to a second. The table, with the paper's
# figures beside ours (`-` where a sequence has no true cameras):

# %%
# NBVAL_CHECK_OUTPUT
PAPER = {
    k: published_value(s, "ours")
    for k, s in [("e3d", "mocap_e3d"), ("e_R", "mocap_rotation_error")]
}
PAPER_PI = published_value("mocap_pseudo_inverse_e3d", "ours-PI")


def cell(v):
    return "-" if v is None else f"{v:.4f}"


print(
    f"{'':8s} {'K':>3s} | {'e3d':>6s} {'paper':>6s} | {'e_R':>6s} {'paper':>6s} | "
    f"{'shape|R':>7s} | {'PI|R':>6s} {'paper':>6s}"
)
for name, r in rows.items():
    print(
        f"{name:8s} {r['K']:3d} | {cell(r['e3d'])} {cell(PAPER['e3d'].get(name))} | "
        f"{cell(r.get('e_R'))} {cell(PAPER['e_R'].get(name))} | {cell(r.get('shape_only')):>7s}"
        f" | {cell(r.get('pseudo_inverse'))} {cell(PAPER_PI.get(name))}"
    )

# %% [markdown]
# Read the columns in pairs. **e3d**: the method against the paper's Table 2 figure; the
# ratio is printed below. **e_R**: the cameras, where the truth has them. **shape|R**: the
# shape stage given the true cameras: close to the full method's e3d on drink, pickup, yoga
# and stretch, so there the rotations cost little. Dance is the exception: its true camera
# does not move at all, and a camera that does not move gives no depth, so the shape stage
# given it does worse than the full method, whose estimated cameras turn (the method
# explains part of the dance as camera motion, hence also dance's large e_R). **PI|R**: the pseudo-inverse shape on the true
# cameras against the paper's Table 1: on the four sequences with moving cameras they differ
# by at most the amount printed below, a tenth of a percent of the error, which confirms
# that our e3d is the paper's (the paper's dance figure comes from estimated cameras).

# %%
ratios = {n: r["e3d"] / PAPER["e3d"][n] for n, r in rows.items()}
print("e3d / paper:", {n: round(v, 2) for n, v in ratios.items()})
if ratios:
    print(
        f"largest ratio {max(ratios.values()):.2f} ({max(ratios, key=ratios.get)}), "
        f"{sum(v <= 1 for v in ratios.values())} of {len(ratios)} at or below the paper"
    )
moving = [n for n in ("drink", "pickup", "yoga", "stretch") if n in rows]
d_pi = max((abs(rows[n]["pseudo_inverse"] - PAPER_PI[n]) for n in moving), default=0)
print(f"pseudo-inverse on the true cameras: largest difference from Table 1 {d_pi:.1e}")
for name, r in rows.items():
    if r["warned"]:
        print(f"{name:8s} warned: {', '.join(r['warned'])}")

# %% [markdown]
# All eight are close to the paper (the largest ratio is printed), about half of them
# below it. A run listed as warned says `W-depth-undetermined`: its cameras leave the depth
# of the moving parts open, so the prior, not the images, sets that depth; the error is
# still the paper's measure, and the warning says why W alone cannot vouch for it.

# %%
if rows:
    names = list(rows)
    x = np.arange(len(names))
    fig, ax = plt.subplots(figsize=(8, 3))
    ax.bar(x - 0.2, [PAPER["e3d"][n] for n in names], 0.4, label="paper (Table 2)")
    ax.bar(x + 0.2, [rows[n]["e3d"] for n in names], 0.4, label="this code")
    ax.set(yscale="log", ylabel="e3d", title="MoCap: the method beside the paper")
    ax.set_xticks(x, names)
    ax.legend()
    plt.show()

# %% [markdown]
# On a log scale the pairs of bars are level on every sequence; dance is the hardest for
# both (its error is about ten times the others').
#
# ## The recording
#
# The recording of pickup shows the reconstruction over the ground truth (the 3D view, the
# largest; the cameras are in the recording too, under `/world/cameras`), the measured and
# re-projected tracks, and e3d per frame.

# %%
import rerun.blueprint as rrb

layout = rrb.Blueprint(
    rrb.Horizontal(
        rrb.Spatial3DView(origin="/world/shapes", name="pickup: estimate (orange), truth (blue)"),
        rrb.Vertical(
            rrb.Spatial2DView(origin="/image", name="W_f: measured and re-projected"),
            rrb.TimeSeriesView(origin="/errors/e3d", name="e3d per frame"),
        ),
        column_shares=[3, 2],
    ),
    rrb.TimePanel(state="collapsed", timeline="frame"),
    collapse_panels=True,
)
if HAVE_DATA:
    rrd = save_recording(result, output_path("06_mocap_pickup.rrd"), pickup, blueprint=layout)
    print(f"wrote {shown_path(rrd)} ({rrd.stat().st_size / 1e6:.1f} MB)")
    show_recording(rrd)

# %% [markdown]
# ![The recording in the Rerun web viewer](../docs/notebooks/recordings/06_mocap_benchmark.png)
#
# Play the frame timeline: the orange estimate stays inside the blue rings of the truth,
# and the per-frame error below stays low.
#
# ## Summary
#
# - e3d aligns each frame by a similarity (scale, rotation or reflection, translation) and
#   measures the relative error; it is the paper's measure, checked by the pseudo-inverse
#   row that reproduces Table 1.
# - The method reproduces the paper's MoCap figures on all eight sequences.
# - Given the true cameras, the shape stage alone is close to the full method where the
#   camera moves: there the rotations are not the limit. A camera that does not move
#   (dance's) gives no depth.
#
# ## Exercises
#
# 1. Change `frame_error` so that it does not allow reflections (force det(Q) = +1). Does
#    e3d of pickup change? Why could it?
# 2. Run pickup with half the paper's K. Is e3d better or worse?
# 3. Why do face, walking and shark have no `shape|R` or `PI|R` entry?
#
# <details><summary>Answers</summary>
#
# - To 1: on pickup it changes nothing, since the reconstruction's depth sign is right; a
#   frame reconstructed mirrored would get a large error without reflections, which is
#   why the paper's measure allows them.
# - To 2: worse: with fewer basis shapes the model cannot follow pickup's motion.
# - To 3: their data give no true cameras: the motion of the camera is inside the shapes,
#   so only the full method can run on them.
#
# </details>


# %% tags=["answers"]
def frame_error_rotation(X_est, X_true):
    A = X_est - X_est.mean(axis=1, keepdims=True)
    B = X_true - X_true.mean(axis=1, keepdims=True)
    U, sv, Vt = np.linalg.svd(B @ A.T)
    D = np.diag([1, 1, np.sign(np.linalg.det(U @ Vt))])
    s = (sv * np.diag(D)).sum() / np.sum(A**2)
    return np.linalg.norm(B - s * U @ D @ Vt @ A) / np.linalg.norm(B)


if HAVE_DATA:
    rot_only = np.mean([frame_error_rotation(a, b) for a, b in zip(result.shapes, pickup.shapes)])
    assert abs(rot_only - by_hand) < 1e-9
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        half = nrsfm.reconstruct(pickup.W, pickup.K // 2).errors(pickup.shapes)["e3d"]
    assert half > rows["pickup"]["e3d"]
    assert all(rows[n].get("shape_only") is None for n in ("face", "walking", "shark"))

# %% tags=["checks"]
if HAVE_DATA:
    assert abs(by_hand - nrsfm.e3d(result.shapes, pickup.shapes)) < 1e-9
    assert len(rows) == 8 and max(ratios.values()) < 1.15  # "close to the paper"
    assert 3 <= sum(v <= 1 for v in ratios.values()) <= 5  # "about half of them below it"
    for name, r in rows.items():
        if name in moving:
            assert abs(r["pseudo_inverse"] / PAPER_PI[name] - 1) < 1.5e-3  # "a tenth of a %"
            assert r["shape_only"] < 1.3 * r["e3d"] + 0.002  # "close to the full method"
    assert rows["dance"]["shape_only"] > 1.5 * rows["dance"]["e3d"]  # "does worse"
    assert {n for n, r in rows.items() if r["warned"]} <= {"dance", "face"}
    assert rows["dance"]["e_R"] > 10 * rows["pickup"]["e_R"]  # "dance's large e_R"
    assert rows["dance"]["e3d"] > 5 * np.median([r["e3d"] for r in rows.values()])

# %% [markdown]
# # 00 · Quickstart: the whole method, once
#
# **What you will learn**
#
# - how to run non-rigid structure from motion with one call, `nrsfm.reconstruct(W, K)`,
#   and what it returns: a camera rotation per frame, a 3D shape per frame, and the
#   intermediate results of every stage;
# - how a reconstruction is judged: against the ground truth (`e3d` for the shapes, `e_R`
#   for the cameras) and without it (the reprojection error), and how far the method's shape
#   prior is ahead of the simplest shape that fits the tracks;
# - what the shape stage's solver does on clean and on noisy tracks, and how to open the
#   Rerun recording of a run.
#
# **Prerequisites**: none of the course; numpy arrays, rotation matrices, least squares
# (the pseudo-inverse). The lessons after this one build each stage by hand.
#
# **Paper**: Kumar & Van Gool, "Organic Priors in Non-Rigid Structure from Motion",
# ECCV 2022: Sec. 2 (the problem, Eq. 1), Sec. 3 (the method: rotations in Sec. 3.1, shape in
# Sec. 3.2, Eq. 9 and Eq. 10), Sec. 4 (how results are measured).
#
# ## The idea
#
# A camera films points on an object that bends, and a tracker follows each point through
# the images. From those 2D tracks alone, the method recovers where the camera looked in
# every frame (a rotation) and the 3D shape of the object in every frame. It works in two
# stages: first the rotations, from a factorisation of the tracks; then the shapes, given
# the rotations, with a prior on how the shapes may vary. Both stages take their prior from
# the data's own factorisation ("organic" priors) rather than from outside knowledge.
#
# The picture first: the built-in synthetic sequence, whose 3D truth is known, seen as the
# method sees it (tracks in the image) and as it should come out (the 3D shape).

# %%
import os

for _v in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_v, "1")  # small matrices: one BLAS thread is fastest

import matplotlib.pyplot as plt
import numpy as np

import data_tools
import nrsfm
from nrsfm.views import figures, output_path, save_recording, show_recording, shown_path

# %%
seq = data_tools.default_sequence()
F, P, K = seq.n_frames, seq.n_points, seq.K
print(f"F = {F} frames, P = {P} points, K = {K} basis shapes; W is {seq.W.shape}")

fig, (ax1, ax2) = plt.subplots(1, 2, figsize=(10, 3.8))
for p in range(0, P, 4):  # every fourth point's path through the image
    ax1.plot(seq.W[0::2, p], seq.W[1::2, p], lw=0.8)
ax1.scatter(seq.W[0], seq.W[1], s=8, c="k", label="frame 0")
ax1.set(title="input: tracks in the image (2D)", xlabel="x", ylabel="y", aspect="equal")
ax1.legend(loc="lower right")
x0, depth0 = seq.shapes[0, 0], seq.shapes[0, 2]  # frame 0 in its camera's frame
ax2.scatter(x0, depth0, s=8, c="k")
ax2.set(title="wanted: frame 0 seen from above", xlabel="x", ylabel="depth z", aspect="equal")
plt.show()

# %% [markdown]
# Each coloured curve is one point moving through the image as the camera turns and the
# object bends; the black dots are frame 0. On the right, the same points of frame 0 seen
# from above: across, the same x as in the image; up, their depth z along the camera's
# viewing direction, which the image does not show. The method gets only the left panel
# and must recover the right one, in every frame.
#
# ## The problem in one equation (Eq. 1)
#
# Frame f's camera is orthographic: it keeps the first two rows
# $\mathbf R_f\in\mathbb R^{2\times3}$ of a rotation, so the tracks of frame f are
# $\mathbf W_f=\mathbf R_f\mathbf X_f$, with $\mathbf X_f$ the $3\times P$ shape (after the mean
# of each row of W is taken off, which removes the camera's translation). The shape mixes K
# basis shapes, $\mathbf X_f=\sum_k c_{fk}\mathbf B_k$. Stacking all frames,
#
# $$\mathbf W=\begin{bmatrix}\mathbf R_1\mathbf X_1\\ \vdots\\ \mathbf R_F\mathbf X_F
#   \end{bmatrix},\qquad \operatorname{rank}\mathbf W\le 3K.\qquad(1)$$
#
# Given only W and K, find every $\mathbf R_f$ and $\mathbf X_f$. Lesson 01 explains the
# rank; lesson 02 (corrective triplets), lesson 03 (registration) and lesson 04 (averaging)
# find the rotations, lesson 05 the shapes.
#
# ## Run it

# %%
result = nrsfm.reconstruct(seq.W, K)  # the paper's method ("organic"), default settings
print(result.summary())

# %% [markdown]
# The summary gives the sizes, the scale the stages work in, the reprojection error (how
# far $\mathbf R_f\mathbf X_f$ is from $\mathbf W_f$, in the input's units: at rounding
# level here) and the time each stage took.
#
# ## What it returns

# %%
# NBVAL_CHECK_OUTPUT
print("rotations", result.rotations.shape, "  shapes", result.shapes.shape)
print("factorization: singular values", result.factorization.singular_values.shape)
rs, ss = result.rotation_stage, result.shape_stage
print(f"rotation stage: {rs.n_triplets} triplets, rotations per triplet {rs.registered.shape}")
print(f"shape stage: solver {ss.solver}, prior {ss.prior}, {ss.n_iter} iterations")

# %% [markdown]
# `rotations` holds one $3\times3$ rotation per frame and `shapes` one $3\times P$ shape per
# frame.
# The stages' results are kept: the SVD of W (`factorization`, lesson 01), the rotation
# stage's K triplets with a rotation per frame each, before they are averaged
# (`rotation_stage`, lesson 02 to lesson 04), and the shape stage (`shape_stage`, lesson 05), whose
# solver is the bilinear one and whose prior is the organic one. Here that solver ran zero
# iterations (why: further down).
#
# We check what the arrays mean with numpy: each $\mathbf R_f$ is a rotation, and the first
# two rows times the shape give the tracks back; the library's `reprojection_error` is that
# RMS.

# %%
R, X = result.rotations, result.shapes
W_f = result.W.reshape(F, 2, P)  # the centred tracks, frame by frame
print(f"tracks per frame W_f {W_f.shape}, cameras R_f {R[:, :2].shape}")
print(f"max |R_f R_f^T - I| = {np.abs(R @ R.transpose(0, 2, 1) - np.eye(3)).max():.0e}")
rms = np.sqrt(np.mean((W_f - R[:, :2] @ X) ** 2))  # Eq. (1), frame by frame
print(
    f"RMS of W_f - R_f X_f by hand {rms:.3e}, reprojection_error() {result.reprojection_error():.3e}"
)

# %% [markdown]
# W cut into frames gives each frame's two rows of tracks, and the camera of a frame is the
# first two rows of its rotation. The rotations are orthonormal to rounding, and the
# hand-computed RMS is the library's number: the shapes explain the tracks to rounding
# error.
#
# ## Judged against the ground truth
#
# A small reprojection error does not prove the 3D is right: the simplest shape that fits
# the tracks, $\mathbf X^{init}_f=\mathbf R_f^{+}\mathbf W_f=\mathbf R_f^\top\mathbf W_f$
# (pseudo-inverse), fits them too but has no depth at all. The shape stage builds its
# prior from it (Eq. 9; the library keeps it as `X_init`). The paper's 3D error `e3d` (Sec. 4) aligns each frame's
# estimate to the truth by the best scale, rotation and reflection (none of which the
# tracks can fix), then takes $\|\mathbf X^{gt}_f-\mathbf X_f\|_F/\|\mathbf X^{gt}_f\|_F$,
# averaged over frames. By hand for frame 0 of the pseudo-inverse shape:

# %%
X0 = R[:, :2].transpose(0, 2, 1) @ W_f  # pinv(R_f) W_f: depth zero
print(f"max |X_init by hand - result.X_init| = {np.abs(X0 - result.X_init).max():.0e}")
A = X0[0] - X0[0].mean(axis=1, keepdims=True)  # centred estimate, frame 0
B = seq.shapes[0] - seq.shapes[0].mean(axis=1, keepdims=True)  # centred truth
U, s, Vt = np.linalg.svd(B @ A.T)  # best rotation (or reflection) U Vt, scale
e0 = np.linalg.norm(B - s.sum() / np.sum(A * A) * (U @ Vt) @ A) / np.linalg.norm(B)
print(
    f"e3d of X_init, frame 0: by hand {e0:.4f}, nrsfm.e3d {nrsfm.e3d(X0, seq.shapes, True)[0]:.4f}"
)

# %% [markdown]
# The library's `X_init` is the one-line numpy version, and `nrsfm.e3d` gives the same
# frame-0 error as the hand computation: the flat shape is off by about half its size.
# Now the whole run against the truth, beside the pseudo-inverse shape with the same
# rotations (`method="pseudo_inverse"`, which also keeps only its best rank-K part).
# `e_R` measures the cameras: one alignment for all frames, then the size of each frame's
# $2\times3$ difference, averaged.

# %%
errors = result.errors(seq.shapes, seq.rotations)
baseline = nrsfm.reconstruct(seq.W, K, method="pseudo_inverse", rotations=R)
e_pi = baseline.errors(seq.shapes)["e3d"]
print(f"organic: e3d {errors['e3d']:.1e}, e_R {errors['e_R']:.1e}")
print(f"pseudo-inverse shape, same rotations: e3d {e_pi:.2f}")

# %% [markdown]
# On this noise-free sequence the method is essentially exact: both errors are below one
# millionth, for the shapes and for the cameras. The pseudo-inverse shape with the very
# same rotations is off by almost half the shape: the rotations alone do not give the
# depth, the shape stage does. Drawn over the truth (blue
# rings; estimate orange, aligned as `e3d` aligns it):

# %%
figures.shapes_figure(result, seq, frames=[0, 75, 149])
plt.show()

# %% [markdown]
# Every orange point sits in its ring, in every frame shown.
#
# ## The shape stage's solver
#
# The shape stage minimises a weighted nuclear norm (Eq. 9, Eq. 10) with a solver that
# iterates (the default, `bilinear`; lesson 05). Its history per iteration is in
# `result.shape_stage.history`. On this noise-free input:

# %%
cost = ss.history["cost"]
print(f"noise-free: {ss.n_iter} iterations, {cost.size} history entry, cost {cost[0]:.1e}")

# %% [markdown]
# The solver stops at its start: its starting point (a closed-form fit, lesson 05) already
# fits W exactly, so the history has a single entry and no curve to draw. To see it
# iterate we add noise to the same sequence (same seed, so the same shapes and cameras):
# Gaussian noise with a standard deviation of one hundredth of W's typical spread.

# %%
noisy = data_tools.make_synthetic(F=150, P=45, K=3, motion="smooth", noise=0.01, seed=7)
print(f"noise 0.01; same truth as above: {np.array_equal(noisy.shapes, seq.shapes)}")
result_n = nrsfm.reconstruct(noisy.W, K)
ss_n = result_n.shape_stage
errors_n = result_n.errors(noisy.shapes, noisy.rotations)
print(f"{ss_n.n_iter} iterations, converged: {ss_n.converged}")
print(f"e3d {errors_n['e3d']:.3f}, e_R {errors_n['e_R']:.3f}")

# %% [markdown]
# With noise the solver iterates 16 times before its stopping rule holds, and the errors
# are no longer at rounding level but small: e3d 0.013 (about the noise level), e_R 0.042.
# Its cost per iteration:

# %%
cost_n, grad_n = ss_n.history["cost"], ss_n.history["grad_norm"]
fig, (ax1, ax2) = plt.subplots(1, 2, figsize=(10, 3.2))
ax1.plot(cost_n, "o-", ms=3, c=figures.EST)
ax1.set(title="cost per iteration (noise 0.01)", xlabel="iteration", ylabel="cost")
ax2.plot(np.log10(grad_n), "o-", ms=3, c="tab:blue")
ax2.axhline(-8, c="gray", ls=":", label="stopping threshold")
ax2.set(title="log10 relative gradient norm", xlabel="iteration")
ax2.legend(loc="upper right")
plt.show()
print(
    f"cost {cost_n[0]:.4e} -> {cost_n[-1]:.4e} ({100 * (1 - cost_n[-1] / cost_n[0]):.1f} % lower)"
)
print(f"relative gradient norm {grad_n[0]:.1e} -> {grad_n[-1]:.1e}")

# %% [markdown]
# The cost falls in the first two iterations and is flat after: the start was already
# close to the minimum, and the whole run lowers the cost by 2.7 %. The solver goes on
# until the relative gradient norm (right; not falling at every step) is below its
# threshold: it stops at a stationary point, not after a fixed number of steps.
#
# ## The recording
#
# `nrsfm.views.save_recording` writes a run to a Rerun file: shapes and cameras per frame
# (timeline `frame`), the image with the measured and the reprojected points, the shape
# stage's history, spectra and a report. We record the noisy run, on which every view has
# something to show. This lesson's layout gives the 3D shapes and cameras the most room,
# with the image and the solver's history beside them.

# %%
import rerun.blueprint as rrb

r1, r2, r3 = noisy.rotations[0]  # the eye: behind camera 0 and above it, at the origin
d = 3.5 * np.linalg.norm(noisy.shapes[0], axis=0).max()
eye = rrb.EyeControls3D(position=-d * (r3 + 0.5 * r2), look_target=[0, 0, 0], eye_up=-r2)
bars = dict(plot_legend=rrb.PlotLegend(visible=False))
world = "shapes (orange estimate, blue truth) and cameras"
image = "image: measured (blue), reprojected (orange)"
gradient = "log10 relative gradient norm (stop at -8)"
layout = rrb.Blueprint(
    rrb.Horizontal(
        rrb.Spatial3DView(origin="/world", name=world, eye_controls=eye),
        rrb.Vertical(
            rrb.Spatial2DView(origin="/image", name=image),
            rrb.BarChartView(origin="/lesson/cost_drop", name="cost removed, %", **bars),
            rrb.BarChartView(origin="/shape_history_bars/grad_norm", name=gradient, **bars),
        ),
        column_shares=[3, 2],
    ),
    rrb.TimePanel(state="collapsed", timeline="frame"),
    collapse_panels=True,
)

# %% [markdown]
# The 3D view looks at the object from behind the first camera, from far enough to hold
# the cameras' paths. The solver's history goes in as bar charts (one bar per iteration),
# because bar charts show on any timeline. The cost barely moves in absolute terms, so the lesson logs its
# drop from the start, in percent, itself (`/lesson/cost_drop`), in a function that
# `save_recording` calls with the open stream.


# %%
def log_cost_drop(rec):
    import rerun as rr

    drop = 100 * (1 - cost_n / cost_n[0])
    rec.log("/lesson/cost_drop", rr.BarChart(drop, abscissa=np.arange(drop.size)), static=True)


rrd = output_path("00_quickstart.rrd")
save_recording(result_n, rrd, noisy, blueprint=layout, extra=log_cost_drop)
print(f"wrote {shown_path(rrd)} ({rrd.stat().st_size / 1e6:.2f} MB)")
show_recording(rrd)

# %% [markdown]
# ![The recording in the Rerun web viewer](../docs/notebooks/recordings/00_quickstart.png)
#
# Play the frame timeline: in the 3D view the orange points stay inside the blue rings
# (close to the truth, not on it: e3d 0.013), and the estimated camera (orange frustum)
# follows the true one along nearly the same path; in the image the reprojected points
# sit on the measured ones. Beside, the cost's drop rises in the first iterations
# and levels off, while the gradient norm goes on down to the stopping threshold.
#
# ## Summary
#
# - `nrsfm.reconstruct(W, K)` returns a rotation per frame and a shape per frame, with
#   every stage's results (`factorization`, `rotation_stage`, `shape_stage`).
# - The reprojection error needs no ground truth but does not judge the depth: the
#   pseudo-inverse shape fits W with none. `e3d` and `e_R` measure against the truth.
# - On clean tracks the method is essentially exact; the pseudo-inverse shape with the
#   same rotations is off by almost half the shape.
# - The shape solver stops at its start on clean input and iterates to a stationary point
#   on noisy input; the recording shows every stage.
#
# ## Exercises
#
# 1. On the noisy run, how far is the pseudo-inverse shape `result_n.X_init` from the
#    truth (`nrsfm.e3d`), next to the final shapes?
# 2. Give `reconstruct` the true cameras (`rotations=seq.rotations`). Which stage does not
#    run, and is the shape still exact?
#
# <details><summary>Answers</summary>
#
# - To 1: about half the shape, as on clean tracks: the noise barely changes it; the final
#   shapes are more than thirty times closer.
# - To 2: the rotation stage is skipped (`result.rotation_stage` is None); the shape
#   stage alone gives the shapes, exact to rounding.
#
# </details>

# %% tags=["answers"]
e_init_n = nrsfm.e3d(result_n.X_init, noisy.shapes)
assert 0.45 < e_init_n < 0.6 and abs(e_init_n - nrsfm.e3d(X0, seq.shapes)) < 0.02
assert e_init_n > 30 * errors_n["e3d"]
r_true = nrsfm.reconstruct(seq.W, K, rotations=seq.rotations)
assert r_true.rotation_stage is None and r_true.errors(seq.shapes)["e3d"] < 1e-6

# %% tags=["checks"]
# What the prose above says, checked on every run (CI).
assert (F, P, K) == (150, 45, 3) and seq.W.shape == (2 * F, P)
assert R.shape == (F, 3, 3) and X.shape == (F, 3, P) and rs.registered.shape[:2] == (K, F)
assert ss.solver == "bilinear" and ss.prior == "organic"
assert np.abs(R @ R.transpose(0, 2, 1) - np.eye(3)).max() < 1e-12
assert abs(rms - result.reprojection_error()) <= 1e-12 * np.std(seq.W)
assert rms < 1e-6 * np.std(seq.W)  # "at rounding level"
assert np.abs(X0 - result.X_init).max() < 1e-12
assert np.abs(R[:, :2] @ X0 - W_f).max() < 1e-12  # X_init fits the tracks too
assert abs(e0 - nrsfm.e3d(X0, seq.shapes, True)[0]) < 1e-12 and 0.45 < e0 < 0.55  # "about half"
assert errors["e3d"] < 1e-6 and errors["e_R"] < 1e-6  # "exact to rounding"
assert 0.35 < e_pi < 0.5  # "almost half the shape"
assert ss.n_iter == 0 and cost.size == 1  # stops at its start
assert np.array_equal(noisy.shapes, seq.shapes) and np.array_equal(noisy.rotations, seq.rotations)
assert ss_n.n_iter == 16 and ss_n.converged and cost_n.size == 17
assert 0.5 * 0.01 < errors_n["e3d"] < 2 * 0.01  # "about the noise level"
assert round(errors_n["e3d"], 3) == 0.013 and round(errors_n["e_R"], 3) == 0.042
assert np.all(np.diff(cost_n) <= 1e-12 * cost_n[0])  # the cost never rises
drop = 1 - cost_n / cost_n[0]
assert drop[2] > 0.99 * drop[-1]  # falls in the first two iterations, flat after
assert round(100 * drop[-1], 1) == 2.7 and grad_n[-1] <= 1e-8 < grad_n[0]
assert rrd.stat().st_size > 10_000

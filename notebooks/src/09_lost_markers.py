# %% [markdown]
# # 09 · Lost markers: completing W, filling from the neighbours, and how far to trust it
#
# **What you will learn**
#
# - why the completion of W (rank 3K) pins a missing marker only if the marker was seen in
#   enough frames, and how the fill gain tells which tracks the data leave undetermined;
# - how the library fills an undetermined marker in 3D from its neighbours: three fills
#   made from the markers seen around it and the model's own, and their median, built by
#   hand for one marker;
# - how far to trust such a fill: how far the four fills stray from their median, against
#   the error to the truth and against the rigid-neighbour fill of motion-capture software.
#
# **Prerequisites**: lessons 01 (W and its rank 3K), 05 (the shape stage), 06 (MoCap and
# e3d); least squares; the rotation that best maps one point set onto another (Kabsch, as
# in the registration of lesson 03).
#
# **Paper**: Sec. 4 (the missing-data experiment: trajectories removed from W, W completed,
# then the method run on it) and Eq. (1). The fill from the neighbours and its reliability
# are this library's additions, not the paper's.
#
# ## The idea
#
# A marker that falls off part-way through a take leaves its column of W empty from then
# on. If the body were exactly a mix of K basis shapes (Eq. 1), the rest of the column
# would follow from the part that was seen: fit the marker's 3K coefficients on its seen
# frames, and the motion of the whole body carries it on. That works when the marker was
# seen long enough. Seen only briefly, the fit is an extrapolation that multiplies the
# measurement noise, and the data leave the marker undetermined. For such markers the
# library turns to the neighbours: markers on the same limb move almost rigidly together.
# It makes several fills in different ways; where they agree the fill can be trusted, where
# they disagree it cannot.
#
# The picture first, on a small synthetic sequence (no data needed): how much a lost
# track's fill multiplies the measurement noise, against the number of frames it was seen
# in before it was lost.

# %%
import os
import warnings

for _v in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_v, "1")

import matplotlib.pyplot as plt
import numpy as np
from IPython import get_ipython
from scipy.stats import spearmanr

import data_tools
import nrsfm
from nrsfm import paths
from nrsfm.experiments.fill import e3d_seen, lost_point_means, point_errors, rigid_neighbour_fill
from nrsfm.geometry import project_to_so3
from nrsfm.stages.completion import MAX_GAIN, choose_lags, fill_gain
from nrsfm.stages.fill import AFFINE_NEIGHBOURS, RIDGE, RIGID_NEIGHBOURS, SPREAD_MAX, fill_unseen
from nrsfm.stages.measurement import factorize
from nrsfm.views import output_path, recording_content, save_recording, show_recording, shown_path
from nrsfm.warnings_catalog import ids_in

# %%
toy = data_tools.make_synthetic(F=80, P=20, K=2, motion="smooth", seed=3)
F_toy, K_toy = toy.n_frames, toy.K
M = factorize(toy.W, K_toy).M_hat  # the motion factor (2F x 3K) of the complete W
n_seen = np.arange(3, F_toy + 1)  # track j seen in frames 0 .. n_seen[j] - 1, then lost
seen_toy = np.arange(F_toy)[:, None] < n_seen[None, :]
gain_lib = fill_gain(M, seen_toy)  # the library's fill gain, one value per track
print(f"F = {F_toy}, K = {K_toy}: 3K = {3 * K_toy} coefficients per track; MAX_GAIN = {MAX_GAIN}")

fig, ax = plt.subplots(figsize=(6, 3.4))
ax.semilogy(n_seen, gain_lib, "o-", ms=3)
ax.axhline(MAX_GAIN, color="tab:red", ls="--", label="MAX_GAIN: undetermined above")
ax.axhline(1.0, color="gray", ls=":", label="as noisy as a measurement")
ax.set(xlabel="frames seen before the track is lost", ylabel="fill gain")
ax.set_title("how much a lost track's fill multiplies the noise")
ax.legend(fontsize=8)
plt.show()

# %% [markdown]
# A track seen for a few frames only has a fill that multiplies the noise by hundreds;
# seen for most of the sequence, its fill is no noisier than a measurement. The dashed line
# at `MAX_GAIN` is where the library stops trusting the completion and calls a track
# undetermined.
#
# ## The fill gain, by hand
#
# Write the two rows of frame f of the motion factor as $\mathbf M_f$ (2 x 3K) and track
# p's column of the shape factor as $\mathbf b_p$ (3K numbers), so that its image point is
# $\mathbf w_{fp}=\mathbf M_f\mathbf b_p$ (Eq. 1). From the frames it was seen in, least
# squares gives $\hat{\mathbf b}_p=\mathbf A_p^{-1}\sum_{f\ \text{seen}}\mathbf M_f^\top
# \mathbf w_{fp}$ with $\mathbf A_p=\sum_{f\ \text{seen}}\mathbf M_f^\top\mathbf M_f$. If
# each measured coordinate carries noise of standard deviation $\sigma$, the fill
# $\mathbf M_f\hat{\mathbf b}_p$ of any frame has covariance
# $\sigma^2\mathbf M_f\mathbf A_p^{-1}\mathbf M_f^\top$, and the gain is its largest
# standard deviation in units of $\sigma$, over the frames:
#
# $$g_p=\max_f\sqrt{\lambda_\max\!\left(\mathbf M_f\mathbf A_p^{-1}\mathbf M_f^\top\right)}.$$

# %%
# NBVAL_CHECK_OUTPUT
Mf = M.reshape(F_toy, 2, 3 * K_toy)  # frame f's two rows


def gain_by_hand(seen):
    A = np.einsum("fri,frj->ij", Mf[seen], Mf[seen])  # A_p, from the seen frames
    cov = Mf @ np.linalg.inv(A) @ Mf.transpose(0, 2, 1)  # M_f A_p^-1 M_f', every frame
    return np.sqrt(np.linalg.eigvalsh(cov)[:, -1].max())


gain_hand = np.array([gain_by_hand(seen_toy[:, j]) for j in range(n_seen.size)])
gap = np.abs(gain_hand / gain_lib - 1).max()
print(f"max relative difference, by hand against fill_gain: {gap:.0e}")
for n in (3, 5, 8, 10, 15, 20, 40, 80):
    print(f"  seen in {n:2d} frames: gain {gain_hand[n - 3]:.3g}")

# %% [markdown]
# By hand and the library's `fill_gain` agree to rounding. Three frames (six rows for six
# coefficients) are the least that determine $\mathbf b_p$ at all, and there the gain is in
# the thousands; it falls below `MAX_GAIN` between 10 and 15 frames and below one well
# before the track is seen throughout. That it is the noise's multiplier can be checked by
# simulation: noise on the seen rows of a track seen in 8 frames, the coefficients fitted,
# the fill's largest standard deviation measured.

# %%
rng = np.random.default_rng(0)
seen8 = np.arange(F_toy) < 8
rows8 = np.repeat(seen8, 2)  # the seen rows of W (x and y of each seen frame)
noise = rng.standard_normal((4000, rows8.sum()))  # sigma = 1
b_fit = np.linalg.lstsq(M[rows8], noise.T, rcond=None)[0]  # one fit per noise draw
fills = (M @ b_fit).T.reshape(-1, F_toy, 2)  # the fill's error in every frame
cov_mc = np.einsum("tfi,tfj->fij", fills, fills) / fills.shape[0]
print(f"simulated largest std of the fill: {np.sqrt(np.linalg.eigvalsh(cov_mc)[:, -1].max()):.2f}")
print(f"fill gain of the same track: {gain_by_hand(seen8):.2f}")

# %% [markdown]
# The simulated standard deviation matches the gain to within the simulation's own
# scatter: a track seen in 8 frames has its fill about six times noisier than a
# measurement, beyond `MAX_GAIN`.
#
# ## Pickup with markers lost part-way (needs `NRSFM_DATA`)
#
# The rest of the lesson uses MoCap pickup; `NRSFM_DATA` names the folder that holds
# `mocap/`. Without it, the next cell says so and every later cell is skipped (it hands
# IPython a filter that empties the cells before they run).

# %%
MOCAP = paths.data_dir() / "mocap" if os.environ.get("NRSFM_DATA") else None
HAVE_DATA = MOCAP is not None and (MOCAP / "pickup.mat").is_file()
if HAVE_DATA:
    print(f"MoCap data found: {(MOCAP / 'pickup.mat').name}")
else:
    print("no MoCap data (set NRSFM_DATA to the folder holding mocap/): the rest is skipped")
    get_ipython().input_transformers_cleanup.append(lambda lines: [])  # later cells: empty

# %% [markdown]
# `data_tools.drop_tracks(W, 0.3, seed=31, pattern="lost")` picks that fraction of the
# markers (rounded) and loses each from a random frame after the first tenth of the take to
# its end (the benchmark's lost-markers task).

# %%
seq = data_tools.load_mocap("pickup", data_dir=MOCAP)
W, observed = data_tools.drop_tracks(seq.W, 0.3, seed=31, pattern="lost")
F, P, K = seq.n_frames, seq.n_points, seq.K
lost = np.flatnonzero(~observed.all(axis=0))
print(f"pickup: F = {F}, P = {P}, K = {K}; {lost.size} markers lost ({lost.size / P:.0%})")
print(f"{100 * (1 - observed.mean()):.1f} % of the entries of W missing (NaN)")

fig, ax = plt.subplots(figsize=(10, 2.6))
ax.imshow(observed.T, aspect="auto", cmap="gray", interpolation="nearest")
ax.set(xlabel="frame", ylabel="marker", title="observed (white) and lost (black)")
plt.show()

# %% [markdown]
# Each black bar is a marker lost from some frame to the end of the take. Some are lost
# early (long bars), some late.
#
# ## The completion of W
#
# `nrsfm.reconstruct` takes the NaN entries as they are: it completes W at rank 3K first,
# then runs the stages of the other lessons on the completed matrix. Each frame's two rows
# have 3K + 1 unknowns (3K coefficients and the translation); a frame in which fewer
# markers are seen cannot pin them, so the completion also uses the frames just before and
# after (time lags), whose rows are nearly the same (`choose_lags`).

# %%
print(f"fewest markers seen in a frame: {observed.sum(axis=1).min()}; 3K + 1 = {3 * K + 1}")
print(f"choose_lags: {choose_lags(observed, 3 * K)}")
with warnings.catch_warnings(record=True) as caught:  # its warning: printed, explained below
    warnings.simplefilter("always")
    result = nrsfm.reconstruct(W, K)
c = result.completion
print(f"completion: {c.method}, lags {c.lags}, {c.n_iter} iterations, converged {c.converged}")
warned = [i for w in caught for i in ids_in(w.message)]
print(f"warnings: {len(caught)}, ids {warned}; unreliable markers: {result.unreliable.sum()}")

# %% [markdown]
# The frame with fewest markers sees fewer than the unknowns of its rows, so the rule
# asks for the lags -1, 0, 1, and the completion (soft-impute, a nuclear-norm completion;
# `docs/studies/missing_data.md` says why) converges. The run issues one warning,
# `W-fills-unreliable`: 5 markers were seen in too few frames for the data to determine
# their 3D, and the fills the library makes for them from their neighbours (built below)
# disagree, so their 3D after they were lost may be far off. The rest of this lesson shows
# where that judgement comes from and how far off those markers are. How good are the
# completed entries?
# Per lost marker: the frames it was seen in, its fill gain, and the error of its
# completed image points against the true ones (RMS over its missing entries, in units of
# W's RMS).

# %%
missing = ~observed
err2d = (result.W_completed - seq.W).reshape(F, 2, P)
err2d = np.sqrt((err2d**2).sum(axis=1).sum(axis=0, where=missing) / missing.sum(axis=0).clip(1))
err2d /= np.sqrt((seq.W**2).mean() * 2)  # per point: x and y
gain = result.fill_gain
print("marker  seen  fill gain  undetermined  2D error")
for p in lost:
    g = f"{gain[p]:9.1f}" if np.isfinite(gain[p]) else "      inf"
    u = str(result.undetermined[p])
    print(f"{p:6d} {observed[:, p].sum():5d}  {g}  {u:>12s}  {err2d[p]:8.3f}")

# %% [markdown]
# The markers seen in most of the take have a gain near or below `MAX_GAIN` and small
# errors in the image. Those lost earlier have gains from several to hundreds (one is not
# determined at all: infinite gain) and mostly larger image errors, up to nearly ten times
# the largest of the determined markers. Their 3D is an extrapolation: these are the
# `undetermined` markers, and the library fills their 3D again, from their neighbours,
# after the shape stage.
#
# ## Filling one marker from its neighbours
#
# `nrsfm.stages.fill.fill_unseen` fills each undetermined marker in each frame it was not
# seen in by the per-coordinate median of four fills. We build them by hand for one marker
# in one frame, from the shape stage's shapes (`shape_stage.shapes`, in the units the
# stages ran in): the points seen in the frame are measured, the marker's own is the
# model's fill.

# %%
X = result.shape_stage.shapes  # (F, 3, P)
p = lost[result.undetermined[lost]][0]  # the first undetermined marker
unseen = np.flatnonzero(~observed[:, p])
f = unseen[unseen.size // 2]  # a frame in the middle of its unseen frames
print(f"marker {p}: seen in {observed[:, p].sum()} frames, filled in frame {f}")
print(f"neighbours: {RIGID_NEIGHBOURS} (rigid, template), {AFFINE_NEIGHBOURS} (affine)")

# %% [markdown]
# Its neighbours are ranked by their mean 3D distance to it over the frames where both
# were seen (at least three); each fill uses the first ones seen in frame f.


# %%
def ranked_neighbours(p):
    both = observed & observed[:, [p]]  # frames where p and q were both seen
    d = np.linalg.norm(X - X[:, :, [p]], axis=1)  # (F, P) distances to p
    mean = np.where(both, d, 0).sum(axis=0) / np.maximum(both.sum(axis=0), 1)
    mean[(both.sum(axis=0) < 3) | (np.arange(P) == p)] = np.inf
    order = np.argsort(mean, kind="stable")
    return order[np.isfinite(mean[order])]


def kabsch(A, B):  # R, a, b: R (x - a) + b carries A (3, k) onto B (3, k)
    a, b = A.mean(axis=1), B.mean(axis=1)
    return project_to_so3((B - b[:, None]) @ (A - a[:, None]).T), a, b


def near_f_of(p, f):  # p's neighbours seen in frame f, nearest first
    near = ranked_neighbours(p)
    return near[observed[f, near]]


print(f"nearest neighbours of marker {p} seen in frame {f}: {near_f_of(p, f)[:AFFINE_NEIGHBOURS]}")

# %% [markdown]
# **Rigid**: take the frame r nearest in time where the marker was seen (for a lost
# marker, its last one), the 4 neighbours nearest to it there that are seen in both r and
# f, and carry the marker with the rotation and translation that carry them from r to f.


# %%
def rigid_fill(p, f):
    seen_p = np.flatnonzero(observed[:, p])
    r = seen_p[np.argmin(np.abs(seen_p - f))]  # nearest seen frame (earlier on a tie)
    nb = near_f_of(p, f)
    nb = nb[observed[r, nb]]
    dist = np.linalg.norm(X[r][:, nb] - X[r][:, [p]], axis=0)
    nb = nb[np.argsort(dist, kind="stable")][:RIGID_NEIGHBOURS]
    R, a, b = kabsch(X[r][:, nb], X[f][:, nb])
    return R @ (X[r][:, p] - a) + b


print(f"rigid fill: {np.array2string(rigid_fill(p, f), precision=3)}")

# %% [markdown]
# **Template**: the marker's place among its 4 nearest neighbours, averaged over every
# frame it was seen with all of them: align those frames' neighbour sets to a common
# template (a few rounds of Kabsch onto their mean, generalised Procrustes), average the
# marker's position in it, then carry the template onto the neighbours in frame f.


# %%
def template_fill(p, f):
    nb = near_f_of(p, f)[:RIGID_NEIGHBOURS]
    fr = np.flatnonzero(observed[:, p] & observed[:, nb].all(axis=1))
    A = X[fr][:, :, nb]
    centre = A.mean(axis=2)
    A, x = A - centre[:, :, None], X[fr][:, :, p] - centre  # centred neighbours, marker
    Z = A[0]
    for _ in range(3):  # generalised Procrustes: rotate every frame onto the mean
        Rs = project_to_so3(Z[None] @ A.transpose(0, 2, 1))
        Z = (Rs @ A).mean(axis=0)
    z = np.einsum("nij,nj->i", Rs, x) / fr.size  # the marker in the template
    R, a, b = kabsch(Z, X[f][:, nb])
    return R @ (z - a) + b


print(f"template fill: {np.array2string(template_fill(p, f), precision=3)}")

# %% [markdown]
# **Affine**: the marker as the centroid of its 6 nearest neighbours plus a weighted sum of
# their offsets from it, $\mathbf x=\bar{\mathbf n}+\sum_j\beta_j(\mathbf n_j-\bar{\mathbf
# n})$, the weights fitted by least squares (with a small ridge) on the frames it was seen
# with them.


# %%
def affine_fill(p, f):
    nb = near_f_of(p, f)[:AFFINE_NEIGHBOURS]
    fr = np.flatnonzero(observed[:, p] & observed[:, nb].all(axis=1))
    A = X[fr][:, :, nb]
    centre = A.mean(axis=2)
    D, y = A - centre[:, :, None], X[fr][:, :, p] - centre
    G, h = np.einsum("rik,ril->kl", D, D), np.einsum("rik,ri->k", D, y)
    ridge = RIDGE * np.trace(G) / nb.size
    beta = np.linalg.solve(G + ridge * np.eye(nb.size), h)
    B = X[f][:, nb]
    return B.mean(axis=1) + (B - B.mean(axis=1, keepdims=True)) @ beta


print(f"affine fill: {np.array2string(affine_fill(p, f), precision=3)}")

# %% [markdown]
# The fourth is the model's own fill, `X[f][:, p]`. The library keeps the per-coordinate
# median of the four; we compare it with `fill_unseen` on the same shapes.


# %%
def four_fills(p, f):  # (4, 3): rigid, template, affine, the model's
    return np.stack([rigid_fill(p, f), template_fill(p, f), affine_fill(p, f), X[f][:, p]])


four = four_fills(p, f)
median = np.median(four, axis=0)  # per coordinate (of four: the mean of the middle two)
X_filled, spread = fill_unseen(X, observed, result.undetermined)
print(f"median of the four: {np.array2string(median, precision=4)}")
print(f"max |median - fill_unseen| = {np.abs(median - X_filled[f][:, p]).max():.0e}")
stray = np.linalg.norm(four - median, axis=1)
print(f"distances of the four fills to their median: {np.array2string(stray, precision=3)}")

# %% [markdown]
# The hand-made median is the library's fill to rounding. The four fills stray from it by
# different amounts: that stray is the library's measure of how far to trust the fill.
#
# ## How far to trust a fill: the spread
#
# For each undetermined marker, the spread is the median of the four fills' distances to
# their median in each unseen frame, taken as an RMS over those frames and divided by the
# shapes' RMS radius. Above `SPREAD_MAX` the library calls the marker `unreliable`. By hand,
# for our marker:

# %%
strays = []
for g in unseen:  # every frame the marker was not seen in
    fills_g = four_fills(p, g)
    strays.append(np.median(np.linalg.norm(fills_g - np.median(fills_g, axis=0), axis=1)))
centred = X - X.mean(axis=2, keepdims=True)
radius = np.sqrt((centred**2).sum() / (F * P))  # the shapes' RMS radius
spread_p = np.sqrt(np.mean(np.square(strays))) / radius
print(f"marker {p}: spread by hand {spread_p:.4f}, fill_spread {result.fill_spread[p]:.4f}")
print(f"SPREAD_MAX = {SPREAD_MAX}; unreliable: {result.unreliable[p]}")

# %% [markdown]
# By hand and the pipeline's `fill_spread` agree, and `fill_unseen` on the shape stage's
# shapes is exactly the pipeline's last step (the same spreads for every marker, checked
# at the end). This marker's fills agree well: below `SPREAD_MAX`, it is trusted.
#
# ## Against the truth and a rigid-neighbour baseline
#
# With the ground truth we can see whether the spread is right to trust or distrust a
# fill. The error of a filled point is its distance to the true one after e3d's per-frame
# alignment, in units of the frame's RMS radius (`point_errors`); each lost marker's
# error is the mean over its unseen frames. The baseline is what motion-capture software
# offers: every lost marker carried rigidly with its 4 nearest neighbours from the last
# frame it was seen in (`rigid_neighbour_fill`), the rigid fill above alone.

# %%
fill_err = lost_point_means(point_errors(result.shapes, seq.shapes), observed)
rigid_only = rigid_neighbour_fill(result.shapes, observed)
base_err = lost_point_means(point_errors(rigid_only, seq.shapes), observed)
print(f"e3d over all points {result.errors(seq.shapes)['e3d']:.4f}, ", end="")
print(f"over the points seen in each frame {e3d_seen(result.shapes, seq.shapes, observed):.4f}")
print("marker  undetermined  spread  unreliable  fill error  baseline")
for q in lost:
    s = f"{result.fill_spread[q]:6.3f}" if np.isfinite(result.fill_spread[q]) else "     -"
    print(
        f"{q:6d}  {str(result.undetermined[q]):>12s}  {s}  {str(result.unreliable[q]):>10s}"
        f"  {fill_err[q]:10.3f}  {base_err[q]:8.3f}"
    )

# %% [markdown]
# The points seen in each frame are reconstructed well; the error is in the lost markers,
# and most of it in those lost early. The markers the completion determines keep the
# model's fill, with small errors. Among the undetermined ones, the trusted (small spread)
# have small errors, and the largest errors are all flagged unreliable.

# %%
und = lost[result.undetermined[lost]]
rho = spearmanr(result.fill_spread[und], fill_err[und]).correlation
print(f"Spearman correlation of spread and error, {und.size} undetermined markers: {rho:.2f}")
mean_fill, mean_base = fill_err[lost].mean(), base_err[lost].mean()
print(f"mean fill error of the lost markers: {mean_fill:.3f}, baseline {mean_base:.3f}")
fig, ax = plt.subplots(figsize=(5.8, 3.8))
red = result.unreliable[und]
ax.scatter(result.fill_spread[und][~red], fill_err[und][~red], c="tab:olive", label="trusted")
ax.scatter(result.fill_spread[und][red], fill_err[und][red], c="tab:red", label="unreliable")
ax.axvline(SPREAD_MAX, color="tab:orange", ls="--", label="SPREAD_MAX")
ax.set(xlabel="spread (how far the four fills stray)", ylabel="fill error (vs the truth)")
ax.set_title("undetermined markers: spread against error")
ax.legend(fontsize=8)
plt.show()

# %% [markdown]
# The spread ranks the fills almost as the truth does: the larger the spread, the larger
# the error. The neighbour fill is also better than the rigid-neighbour baseline on
# average (not on every marker), most on markers lost early, where one rigid carry from a
# frame long past drifts.
#
# ## The recording
#
# The recording zooms in on the body, as the largest view: per frame, the reconstruction
# (`/world/shapes/estimate`, orange), the markers not seen in the frame
# (`/world/shapes/filled`, larger points coloured by reliability: yellow at 0 spread,
# orange at `SPREAD_MAX`, red at twice that and beyond) and the ground truth
# (`/world/shapes/ground_truth`, blue dots in rings), with a line from each filled
# undetermined marker to its true place (`/lesson/fill_to_truth`, logged by the lesson).
# Beside it, per frame, the mean error of those markers' fill and of the baseline
# (`/lesson/fill_error/...`), and the run's report (`/run/report`).

# %%
import rerun as rr
import rerun.blueprint as rrb

content = recording_content(result, seq)  # what the recording draws, aligned to the truth
extent = np.linalg.norm(content.shapes_gt, axis=2).max()  # the body's size in the view
r1, r2, r3 = content.cameras_gt[0]  # the first camera's axes, to look from near it
eye_dir = -r3 + 0.5 * r1 - 0.3 * r2
target = -0.15 * extent * r2  # a little above the centroid: the body bends forward
eye_pos = target + 2.0 * extent * eye_dir / np.linalg.norm(eye_dir)
eye = rrb.EyeControls3D(position=eye_pos, look_target=target, eye_up=-r2)
body = ["+ /world/shapes/**", "+ /lesson/fill_to_truth/**"]
title = "filled markers (yellow trusted ... red unreliable), truth (blue rings)"
layout = rrb.Blueprint(
    rrb.Horizontal(
        rrb.Spatial3DView(origin="/", contents=body, name=title, eye_controls=eye),
        rrb.Vertical(
            rrb.TimeSeriesView(origin="/lesson/fill_error", name="fill error per frame"),
            rrb.TextDocumentView(origin="/run/report", name="the run's report"),
        ),
        column_shares=[3, 2],
    ),
    rrb.TimePanel(state="collapsed", timeline="frame"),
    collapse_panels=True,
)
print(f"the body's extent in the view: {extent:.2f}")

# %% [markdown]
# The lines from fill to truth and the per-frame errors are the lesson's own: a function
# that `save_recording` calls with the open stream logs them.

# %%
show = ~observed & result.undetermined[None, :]  # (F, P): the filled undetermined markers
frames = np.flatnonzero(show.any(axis=1))
seg = np.stack([content.shapes_est, content.shapes_gt], axis=2)[show]  # (n, 2, 3)
err_fill, err_base = point_errors(result.shapes, seq.shapes), point_errors(rigid_only, seq.shapes)
per_frame = {
    name: np.array([e[g][show[g]].mean() for g in frames])
    for name, e in (("neighbour_fill", err_fill), ("rigid_baseline", err_base))
}


def log_lesson(rec):
    index = [rr.TimeColumn("frame", sequence=frames)]
    lines = rr.LineStrips3D.columns(strips=seg).partition(show[frames].sum(axis=1))
    rec.send_columns("/lesson/fill_to_truth", index, lines)
    style = rr.LineStrips3D.from_fields(colors=[(200, 40, 40, 255)], radii=[0.005 * extent])
    rec.log("/lesson/fill_to_truth", style, static=True)
    for name, v in per_frame.items():
        rec.send_columns(f"/lesson/fill_error/{name}", index, rr.Scalars.columns(scalars=v))


rrd = output_path("09_lost_markers.rrd")
save_recording(result, rrd, seq, blueprint=layout, extra=log_lesson)
print(f"wrote {shown_path(rrd)} ({rrd.stat().st_size / 1e6:.2f} MB)")
show_recording(rrd)

# %% [markdown]
# ![The recording in the Rerun web viewer](../docs/notebooks/recordings/09_lost_markers.png)
#
# In the viewer, play the frame timeline: the filled markers that stay yellow keep close to
# their blue rings, the red ones wander off (long red lines), and the error curves show
# the neighbour fill below the baseline over most of the take.
#
# ## Summary
#
# - The completion of W fits each track's 3K coefficients on the frames it was seen in;
#   the fill gain, $\max_f\sqrt{\lambda_\max(\mathbf M_f\mathbf A_p^{-1}\mathbf M_f^\top)}$,
#   says how much that fill multiplies the noise. Above `MAX_GAIN` the track is
#   `undetermined`: its fill is an extrapolation.
# - MoCap needs the frames around each frame to complete W (time lags): a frame sees fewer
#   markers than the unknowns of its rows.
# - An undetermined marker is filled in 3D, in each frame it was not seen in, by the median
#   of a rigid, a template and an affine fill from its neighbours and the model's own fill
#   (`fill_unseen`, the last step of `reconstruct`).
# - How far the four fills stray from their median (`fill_spread`) ranks the fills by their
#   true error; above `SPREAD_MAX` the marker is `unreliable`, and a run with an unreliable
#   marker warns (`W-fills-unreliable`). The neighbour fill beats the rigid-neighbour
#   baseline on average.
#
# ## Exercises
#
# 1. In the synthetic example, from how many seen frames on is a lost track determined
#    (gain at most `MAX_GAIN`)?
# 2. A track seen in the first 10 and the last 10 frames of the synthetic sequence
#    (occluded in between, not lost) is seen in as many frames as one seen in the first 20.
#    Which has the larger gain, and why?
# 3. The table shows a marker lost only near the end (seen in almost every frame). Why is
#    it not filled from its neighbours, and is its fill good?
#
# <details><summary>Answers</summary>
#
# - To 1: where the curve crosses the dashed line, between 10 and 15 seen frames
#   (`n_seen[gain_hand <= MAX_GAIN][0]` gives the count); the gain falls steeply over the
#   first frames and slowly after.
# - To 2: the track seen at both ends has a gain below one, the one seen in the first
#   frames a larger one: with both ends seen, every unseen frame lies between seen ones and
#   the fill interpolates; seen only at the start, it extrapolates.
# - To 3: its gain is below one, so the completion determines it and the model's fill is
#   kept; its fill error is among the smallest of the table.
#
# </details>

# %% tags=["answers"]
n_det = n_seen[gain_hand <= MAX_GAIN][0]
assert 10 < n_det < 15 and np.all(gain_hand[n_seen >= n_det] <= MAX_GAIN)
ends = (np.arange(F_toy) < 10) | (np.arange(F_toy) >= F_toy - 10)
assert gain_by_hand(ends) < 1 < gain_by_hand(np.arange(F_toy) < 20)
late = lost[np.argmax(observed[:, lost].sum(axis=0))]
assert observed[:, late].sum() > 0.95 * F and gain[late] < 1 and not result.undetermined[late]
assert fill_err[late] <= np.sort(fill_err[lost])[1]  # among the smallest

# %% tags=["checks"]
# What the prose above says, checked on every run (CI).
two = fill_gain(M, (np.arange(F_toy) < 2)[:, None])[0]  # seen in 2 frames: not determined
assert gap < 1e-8 and gain_hand[0] > 1000 and two == np.inf and np.all(np.diff(gain_hand) < 0)
g_at, g8 = dict(zip(n_seen, gain_hand)), gain_by_hand(seen8)
assert g_at[10] > MAX_GAIN > g_at[15] and g_at[40] < 1 and 5.5 < g8 < 6.5
assert abs(np.sqrt(np.linalg.eigvalsh(cov_mc)[:, -1].max()) / g8 - 1) < 0.05
assert observed.sum(axis=1).min() < 3 * K + 1 and choose_lags(observed, 3 * K) == (-1, 0, 1)
assert c.method == "soft_impute" and c.converged
assert warned == ["W-fills-unreliable"] and len(caught) == 1 and result.unreliable.sum() == 5
det, und2 = lost[~result.undetermined[lost]], lost[result.undetermined[lost]]
assert np.all(gain[det] <= MAX_GAIN) and err2d[det].max() < 0.07
assert np.isinf(gain[und2]).sum() == 1 and np.all(gain[und2] > 5)  # several to hundreds
assert 8 < err2d[und2].max() / err2d[det].max() < 10  # "up to nearly ten times"
assert np.mean(err2d[und2] > err2d[det].max()) > 0.5  # "mostly larger"
assert np.abs(median - X_filled[f][:, p]).max() < 1e-12
assert np.allclose(spread, result.fill_spread, rtol=1e-12, atol=1e-15, equal_nan=True)
assert abs(spread_p - result.fill_spread[p]) < 1e-10 and spread_p < SPREAD_MAX
assert e3d_seen(result.shapes, seq.shapes, observed) < 0.3 * result.errors(seq.shapes)["e3d"]
worst = lost[np.argsort(fill_err[lost])[-3:]]  # the three largest fill errors
assert np.all(observed[:, worst].sum(axis=0) < F / 3) and np.all(result.unreliable[worst])
assert fill_err[det].max() < 0.06 and fill_err[und2[~result.unreliable[und2]]].max() < 0.05
assert rho > 0.8 and mean_fill < mean_base and np.any(fill_err[lost] > base_err[lost])
most = lost[np.argmax(base_err[lost] - fill_err[lost])]  # "most on markers lost early"
assert observed[:, most].sum() < F / 3  # and the recording: below the baseline mostly
assert np.mean(per_frame["neighbour_fill"] < per_frame["rigid_baseline"]) > 0.5

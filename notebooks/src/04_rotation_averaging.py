# %% [markdown]
# # 04 · Single rotation averaging: the L1 average against the chordal L2 mean
#
# **What you will learn**
#
# - how the K rotation samples of one frame are averaged: the chordal L2 mean in closed form,
#   and the L1 average by Weiszfeld steps in the tangent space (log and exp maps), started
#   from the element-wise median;
# - why a few far-off samples drag the L2 mean but hardly move the L1 average, and how
#   both degrade as the share of outliers grows;
# - what averaging buys in the pipeline, and why under track noise the average of the
#   triplets' samples (`organic`) is no better than the search's best triplet alone (`bmm`).
#
# **Prerequisites**: lessons 02 and 03 (the triplets, their rotations per frame and their
# registration); rotation matrices, rotation vectors (axis times angle) and
# `scipy.spatial.transform.Rotation`; the median of numbers.
#
# **Paper**: Sec. 3.1 (single rotation averaging), Eq. (4), Eq. (5), Eq. (6), Algorithm 1.
#
# ## The idea
#
# After registration, every frame has one estimate of its camera per triplet. They mostly
# agree to a few degrees; now and then one is far off. Their average should be a rotation
# again, and it should not care about the odd one out.
#
# The plain mean of the matrices, pushed back to the nearest rotation, is the least-squares
# (L2) answer: every sample pulls on it in proportion to how far away it is, so the far ones
# pull hardest. The L1 average minimises the sum of the angles instead: every sample pulls
# with the same strength however far it is, as a median does with numbers. The picture: one
# frame with a dozen samples, most near the truth and three far off to one side. Each
# rotation is drawn as its rotation vector relative to the truth (axis times angle, in
# degrees): the truth sits at the origin.

# %%
import os

for _v in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_v, "1")

import matplotlib.pyplot as plt
import numpy as np
from scipy.spatial.transform import Rotation

import data_tools
import nrsfm
from nrsfm import paths
from nrsfm.geometry import average_rotations, project_to_so3, rotation_angle
from nrsfm.published import published_value
from nrsfm.stages.rotations import filter_rotations, resolve_depth_signs
from nrsfm.views import output_path, recording_content, save_recording, show_recording, shown_path

# %%
rng = np.random.default_rng(4)
R_true = Rotation.random(random_state=5).as_matrix()
m, n_far, jitter_deg, far_deg = 12, 3, 3.0, 40.0
far_axis = np.array([1.0, 0.4, 0.0]) / np.linalg.norm([1.0, 0.4, 0.0])
rotvecs = np.deg2rad(jitter_deg) * rng.standard_normal((m, 3))  # relative to the truth
rotvecs[:n_far] += np.deg2rad(far_deg) * far_axis  # three samples far off, one side
S = Rotation.from_rotvec(rotvecs).as_matrix() @ R_true  # the frame's m samples
L2_lib, L1_lib = project_to_so3(S.mean(axis=0)), average_rotations(S[:, None])[0]
print(f"m = {m} samples: {m - n_far} within about {jitter_deg:.0f} deg, {n_far} near {far_deg:.0f}")


def deg_from_truth(R):
    return np.rad2deg(rotation_angle(R, R_true))


def tangent(R):  # rotation vectors of R relative to the truth, in degrees
    return np.rad2deg(Rotation.from_matrix(R @ R_true.T).as_rotvec()).reshape(-1, 3)


d_L2_lib, d_L1_lib = deg_from_truth(L2_lib), deg_from_truth(L1_lib)
print(f"angle to the truth: L2 mean {d_L2_lib:.1f} deg, L1 average {d_L1_lib:.1f} deg")

# %%
fig, ax = plt.subplots(figsize=(6.5, 4.2))
v = tangent(S)
ax.scatter(v[n_far:, 0], v[n_far:, 1], c="gray", label="samples")
ax.scatter(v[:n_far, 0], v[:n_far, 1], c="tab:red", label="far-off samples")
ax.scatter(0, 0, marker="+", s=200, c="k", label="truth")
for R, name, c in ((L2_lib, "chordal L2 mean", "tab:blue"), (L1_lib, "L1 average", "tab:orange")):
    ax.scatter(*tangent(R)[0, :2], marker="*", s=220, c=c, label=name, edgecolors="k")
ax.set(xlabel="rotation vector x (deg)", ylabel="rotation vector y (deg)", aspect="equal")
ax.set_title("one frame's samples, seen from the truth")
ax.legend(loc="upper left", fontsize=8)
plt.show()

# %% [markdown]
# The grey samples scatter around the truth (the cross), the three red ones sit far to the
# right. The chordal L2 mean (blue star) is dragged several degrees towards them; the L1
# average (orange star) stays in the grey cluster. Both were computed here with the
# library's functions; the rest of the lesson builds them by hand.
#
# ## Two distances between rotations
#
# The geodesic distance is the angle of the rotation that takes $\mathbf R$ to
# $\mathbf R_i$: the length of the rotation vector $\log(\mathbf R_i\mathbf R^\top)$. The
# chordal distance is the plain matrix distance, and it is a function of that angle:
#
# $$d_\angle(\mathbf R_i,\mathbf R)=\|\log(\mathbf R_i\mathbf R^\top)\|,\qquad
#   d_\text{chord}(\mathbf R_i,\mathbf R)=\|\mathbf R_i-\mathbf R\|_F
#   =2\sqrt2\,\sin\frac{d_\angle}{2}.$$

# %%
angle = np.linalg.norm(Rotation.from_matrix(S @ R_true.T).as_rotvec(), axis=1)  # log map
chord = np.linalg.norm(S - R_true, axis=(1, 2))
gap_chord = np.abs(chord - 2**1.5 * np.sin(angle / 2)).max()
gap_angle = np.abs(angle - rotation_angle(S, R_true)).max()
print(f"max |chordal - 2 sqrt(2) sin(angle / 2)| = {gap_chord:.0e}")
print(f"max |log-map angle - rotation_angle| = {gap_angle:.0e}")
print(f"angles of the far samples: {np.array2string(np.rad2deg(angle[:n_far]), precision=1)} deg")

# %% [markdown]
# Both identities hold to rounding: the chordal distance is the geodesic angle bent by a
# sine, and the library's `rotation_angle` (from the trace) is the length of scipy's rotation
# vector. For small angles the two distances are nearly proportional; the chordal one grows
# ever more slowly and stops at $2\sqrt2$ for a half turn.
#
# ## The chordal L2 mean (Eq. 4 with p = 2)
#
# Single rotation averaging looks for the rotation closest to all the samples,
#
# $$\arg\min_{\mathbf R\in SO(3)}\sum_{i=1}^{m}d^p(\mathbf R_i,\mathbf R).\qquad(4)$$
#
# With the chordal distance and $p=2$,
# $\sum_i\|\mathbf R_i-\mathbf R\|_F^2=6m-2\,\mathrm{tr}(\mathbf R^\top\sum_i\mathbf R_i)$,
# so the best $\mathbf R$ is the rotation nearest to the mean matrix
# $\bar{\mathbf R}=\frac1m\sum_i\mathbf R_i$: its projection onto $SO(3)$,
# $\Upsilon(\Psi)=\mathbf U\mathbf D\mathbf V^\top$ from the SVD $\Psi=\mathbf U\Sigma
# \mathbf V^\top$, with $\mathbf D=\mathrm{diag}(1,1,\det\mathbf U\mathbf V^\top)$ so that it
# is never a reflection (the paper's $\Upsilon$, with Eq. 6).


# %%
def project(A):  # the nearest rotation to the 3 x 3 matrix A (Upsilon)
    U, _, Vt = np.linalg.svd(A)
    return U @ np.diag([1.0, 1.0, np.sign(np.linalg.det(U @ Vt))]) @ Vt


R_bar = S.mean(axis=0)
L2 = project(R_bar)
print("singular values of the mean matrix:", np.array2string(np.linalg.svd(R_bar)[1], precision=3))
print(f"max |project - project_to_so3| = {np.abs(L2 - project_to_so3(R_bar)).max():.0e}")
print(f"L2 mean: {deg_from_truth(L2):.1f} deg from the truth")
nearby = Rotation.from_rotvec(np.deg2rad(5) * rng.standard_normal((500, 3))).as_matrix() @ L2
cost_L2 = (np.linalg.norm(S - L2, axis=(1, 2)) ** 2).sum()
costs = (np.linalg.norm(S[None] - nearby[:, None], axis=(2, 3)) ** 2).sum(axis=1)
print(f"chordal cost: at the L2 mean {cost_L2:.3f}, lowest of 500 near it {min(costs):.3f}")

# %% [markdown]
# The mean of the samples is not a rotation (its singular values are below one: averaging
# rotations shrinks them); its projection is, and equals the library's `project_to_so3`.
# No rotation near it has a lower chordal cost. It lies several degrees from the truth: the
# far samples, a quarter of the twelve, pull it towards them.
#
# ## The start of the L1 average: the element-wise median (Eq. 6)
#
# With $p=1$ and the geodesic angle, Eq. (4) for frame f and its registered samples
# $\tilde{\mathbf R}^k_f$ is the paper's Eq. (5),
#
# $$\arg\min_{\mathbf R_f\in SO(3)}\sum_k d_\angle(\tilde{\mathbf R}^k_f,\mathbf R_f).
#   \qquad(5)$$
#
# It has no closed form; Algorithm 1 iterates from a start. The paper starts, not from the
# L2 mean, but from the matrix $\mathbf S_o$ closest to the samples in the entry-wise L1
# sense: each of its nine entries is the median of that entry over the samples (Eq. 6),
# then projected, $\mathbf R_o=\Upsilon(\mathbf S_o)$.

# %%
S_o = np.median(S, axis=0)  # entry by entry
R_o = project(S_o)
print("singular values of the median matrix:", np.array2string(np.linalg.svd(S_o)[1], precision=3))
start_lib = average_rotations(S[:, None], max_iter=0)[0]  # the library's start
print(f"max |R_o - library start| = {np.abs(R_o - start_lib).max():.0e}")
print(f"median start: {deg_from_truth(R_o):.1f} deg from the truth")

# %% [markdown]
# The median matrix is not a rotation either; projected, it is the library's start
# (`average_rotations` with `max_iter=0`). Medians of the entries ignore the three far
# samples, so this start is already much closer to the truth than the L2 mean.
#
# ## Weiszfeld steps in the tangent space (Algorithm 1)
#
# Seen from the current estimate $\mathbf R$, each sample is a rotation vector
# $\mathbf v_i=\log(\mathbf R_i\mathbf R^\top)$ whose length is its angle $d_\angle$. The
# sum of lengths is smallest where the unit vectors $\mathbf v_i/\|\mathbf v_i\|$ cancel.
# Weiszfeld's step is a weighted mean of the $\mathbf v_i$ with weights $1/\|\mathbf v_i\|$
# (far samples count less), applied with the exponential map:
#
# $$\Delta\mathbf v=\frac{\sum_i\mathbf v_i/\|\mathbf v_i\|}{\sum_i1/\|\mathbf v_i\|},
#   \qquad\mathbf R\leftarrow\exp(\Delta\mathbf v)\,\mathbf R,$$
#
# repeated until $\|\Delta\mathbf v\|<10^{-3}$ (at most 50 steps, the paper's setting).


# %%
def weiszfeld(samples, R, eps=1e-3, max_iter=50):
    """L1 average of samples (m, 3, 3) from R (Algorithm 1); the L1 cost (deg) per step."""
    cost = []
    for _ in range(max_iter):
        v = Rotation.from_matrix(samples @ R.T).as_rotvec()  # log map, (m, 3)
        norms = np.linalg.norm(v, axis=1)
        cost.append(np.rad2deg(norms).sum())
        w = 1.0 / np.maximum(norms, 1e-12)
        dv = (w[:, None] * v).sum(axis=0) / w.sum()  # the Weiszfeld step
        R = Rotation.from_rotvec(dv).as_matrix() @ R  # exp map
        if np.linalg.norm(dv) < eps:
            break
    return R, np.array(cost), w / w.sum()


L1, cost, weights = weiszfeld(S, R_o)
st = nrsfm.RotationSettings()  # the library's defaults: the paper's
print(f"RotationSettings: eps = {st.eps}, max_iter = {st.max_iter}")
print(f"L1 cost (sum of angles, deg) per step: {np.array2string(cost, precision=2)}")
print(f"L1 average: {deg_from_truth(L1):.1f} deg from the truth, after {cost.size} steps")
print(f"weight of the {n_far} far samples: {sum(weights[:n_far]):.0%} ({n_far / m:.0%} of them)")

# %% [markdown]
# The L1 cost falls at every step and the loop stops after a few. The average lands close
# to the truth, much closer than the L2 mean; at the end the three far samples hold only a
# few per cent of the weight, although they are a quarter of the samples. The library's
# `average_rotations` is this loop run for all frames at once:

# %%
L1_lib, info_one = average_rotations(S[:, None], return_info=True)
gap_L1 = np.rad2deg(rotation_angle(L1, L1_lib[0]))
print(f"angle between by hand and average_rotations: {gap_L1:.0e} deg")
print(f"library steps: {info_one['iterations'][0]}, converged: {info_one['converged'][0]}")
for name, R in (("median start", R_o), ("L2 mean", L2), ("L1 average", L1)):
    print(f"  L1 cost at the {name:12s} {np.rad2deg(rotation_angle(S, R)).sum():7.2f} deg")

# %% [markdown]
# The two agree to rounding and take the same number of steps. Of the three candidates the
# L1 average has the lowest L1 cost, as it should: it is the minimiser of Eq. (5).
#
# ## Many frames, more outliers
#
# One frame is an anecdote. Below, $F=300$ frames with random true rotations and $m=12$
# samples each: the truth turned by a small random rotation (2 degrees per axis), except a
# fraction of the samples, replaced by uniformly random rotations (outliers). The error is
# the mean angle to the truth over the frames.

# %%
F, m_many, sigma_deg = 300, 12, 2.0
truth = Rotation.random(F, random_state=1).as_matrix()
fractions = [0.0, 0.1, 0.25, 0.4, 0.5]
table = []
for frac in fractions:
    jitter = Rotation.from_rotvec(np.deg2rad(sigma_deg) * rng.standard_normal((m_many * F, 3)))
    S_many = jitter.as_matrix().reshape(m_many, F, 3, 3) @ truth[None]
    outlier = rng.random((m_many, F)) < frac
    S_many[outlier] = Rotation.random(int(outlier.sum()), random_state=2).as_matrix()
    L1_many, info = average_rotations(S_many, return_info=True)
    L2_many = project_to_so3(S_many.mean(axis=0))
    err = [np.rad2deg(rotation_angle(R, truth)).mean() for R in (S_many[0], L1_many, L2_many)]
    table.append((frac, *err, info["iterations"].mean(), info["converged"].all()))
print(f"F = {F} frames, m = {m_many} samples each, {sigma_deg:.0f} deg per axis on the inliers")

# %% [markdown]
# The next cell prints the table: per outlier fraction, the mean error of one sample
# alone, of the L1 average and of the L2 mean, and the mean number of Weiszfeld steps.

# %%
# NBVAL_CHECK_OUTPUT
print("outliers | one sample | L1 average | L2 mean | steps | all converged")
for frac, e_one, e_L1, e_L2, steps, conv in table:
    print(f"{frac:8.2f} | {e_one:10.2f} | {e_L1:10.2f} | {e_L2:7.2f} | {steps:5.1f} | {conv}")
by = {row[0]: row for row in table}

# %% [markdown]
# Without outliers both averages of twelve samples are about three times more accurate
# than one sample alone, and the L2 mean is slightly better than the L1 average (for
# Gaussian noise the mean is the efficient estimate). With outliers the L2 mean degrades
# roughly in proportion to their share; the L1 average stays near the noise level up to a
# quarter of outliers and degrades much more slowly beyond. Every frame converges, in a
# handful of steps on average.

# %%
fig, ax = plt.subplots(figsize=(5.5, 3.4))
lines = ((2, "L1 average (Algorithm 1)", "tab:orange"), (3, "chordal L2 mean", "tab:blue"))
for col, name, colour in lines + ((1, "one sample", "gray"),):
    ax.plot(fractions, [row[col] for row in table], "o-", label=name, color=colour)
ax.set(xlabel="fraction of outlier samples", ylabel="mean error (deg)", yscale="log")
ax.legend(fontsize=8)
ax.grid(alpha=0.3)
plt.show()

# %% [markdown]
# On a log axis: one sample alone is useless as soon as there are outliers (a random
# rotation is off by more than a right angle on average), the L2 mean climbs steadily, the
# L1 average stays lowest at every fraction.
#
# ## In the pipeline: the triplets' samples
#
# In `nrsfm.reconstruct` the samples of frame f are the K registered rotations of lesson 03,
# `rotation_stage.registered` (K, F, 3, 3). The stage averages twice: an L1 average of all
# samples, then the filter keeps the samples within $\delta$ (geodesic, in radians) of it
# (`filter_rotations`), and the final average is of the kept ones. We rebuild both on a
# synthetic sequence with noisy tracks.

# %%
seq = data_tools.make_synthetic(F=150, P=45, K=3, motion="smooth", noise=0.10, seed=31)
result = nrsfm.reconstruct(seq.W, seq.K, seed=1)
rs, delta = result.rotation_stage, result.settings.rotation.delta
print(f"F = {seq.n_frames}, P = {seq.n_points}, K = {seq.K}, noise 0.10; delta = {delta} rad")
first = average_rotations(rs.registered)  # all samples
kept, distance = filter_rotations(rs.registered, first, delta)
averaged = average_rotations(rs.registered, kept)  # the kept samples
same = np.array_equal(kept, rs.kept)
print(f"kept {kept.sum()} of {kept.size} samples; the same as the stage's: {same}")
print(f"max |averaged - rotation_stage.averaged| = {np.abs(averaged - rs.averaged).max():.0e}")

# %% [markdown]
# The filter drops a few samples, exactly those the stage dropped, and the average of the
# rest is the stage's `averaged` to rounding. How good are the samples and their average?
# `nrsfm.rotation_error` is e_R, the paper's camera error (after one global alignment; each
# set gets its depth signs by smoothness first, as in the pipeline, `resolve_depth_signs`).
# Beside it, how far the samples are from each other, in the same measure.


# %%
def e_R(R):
    return nrsfm.rotation_error(resolve_depth_signs(R)[0], seq.rotations)


for k in range(seq.K):
    print(f"  e_R {e_R(rs.registered[k]):.4f}  triplet {k + 1} alone")
print(f"  e_R {e_R(averaged):.4f}  L1 average of the kept samples (the pipeline)")
print(f"  e_R {e_R(project_to_so3(rs.registered.mean(axis=0))):.4f}  L2 mean of all samples")
R2 = rs.registered[..., :2, :]  # the cameras: the first two rows
apart = np.linalg.norm(R2[0] - R2[1:], ord=2, axis=(2, 3)).mean()  # same measure as e_R
e_one = np.mean([e_R(rs.registered[k]) for k in range(seq.K)])
print(f"mean distance of triplets 2 and 3 from triplet 1: {apart:.3f}")
print(f"two samples with independent errors of that size: about {np.sqrt(2) * e_one:.3f} apart")

# %% [markdown]
# Each triplet is off by a similar amount (the third a little more), and the average lands
# among them, no better than the best triplet; the L2 mean is about as good (no outliers
# here). The reason is in the last two lines: the samples are about half as far from each
# other as independent errors of their size would put them. All of them are lifted from
# the same noisy motion factor (lesson 02), so they share most of their error, and an
# average only removes the part in which they disagree. Over four noisy sequences, the
# pipeline (`organic`) against the best triplet of the search alone (`bmm`):

# %%
rows_noise = []
for s_ in range(4):
    sq = data_tools.make_synthetic(F=150, P=45, K=3, motion="smooth", noise=0.10, seed=30 + s_)
    bmm = nrsfm.reconstruct(sq.W, sq.K, method="bmm", seed=s_)
    org = nrsfm.reconstruct(sq.W, sq.K, seed=s_)
    rows_noise.append([nrsfm.rotation_error(r.rotations, sq.rotations) for r in (bmm, org)])
rows_noise = np.array(rows_noise)
print(f"e_R per seed, bmm:     {np.array2string(rows_noise[:, 0], precision=3)}")
print(f"e_R per seed, organic: {np.array2string(rows_noise[:, 1], precision=3)}")
ratio = rows_noise[:, 1].mean() / rows_noise[:, 0].mean()
print(f"mean organic / mean bmm: {ratio:.2f}")

# %% [markdown]
# Under noise the two are within a few per cent of each other on every seed: averaging
# samples with a shared error neither helps nor hurts much. It pays off where the samples'
# errors differ, as in the outlier experiment above.
#
# ## Real motion capture (when `NRSFM_DATA` is set)
#
# On MoCap pickup the triplets disagree in places (the filter drops a few per cent of the
# samples), and the paper reports a lower e_R with averaging than with Dai et al.'s single
# triplet (BMM).

# %%
MOCAP = paths.data_dir() / "mocap" if os.environ.get("NRSFM_DATA") else None
HAVE_DATA = MOCAP is not None and (MOCAP / "pickup.mat").is_file()
if HAVE_DATA:
    pickup = data_tools.load_mocap("pickup", data_dir=MOCAP)
    rp = nrsfm.reconstruct(pickup.W, pickup.K).rotation_stage
    pick = {
        "triplet 1 alone": rp.registered[0],
        "L1 average, kept samples": rp.averaged,
        "L2 mean, kept samples": project_to_so3(
            np.einsum("kf,kfij->fij", rp.kept, rp.registered) / rp.kept.sum(0)[:, None, None]
        ),
    }
    pick = {
        k: nrsfm.rotation_error(resolve_depth_signs(R)[0], pickup.rotations)
        for k, R in pick.items()
    }
    print(f"pickup: K = {pickup.K}, kept {rp.kept.mean():.0%} of {rp.kept.size} samples")
    for k, v in pick.items():
        print(f"  e_R {v:.4f}  {k}")
    paper = {c: published_value("mocap_rotation_error", c)["pickup"] for c in ("ours", "BMM")}
    print(f"  the paper: ours {paper['ours']}, BMM {paper['BMM']}")
else:
    print("no MoCap data (set NRSFM_DATA to the folder holding mocap/): this part skipped")

# %% [markdown]
# With the data, the L1 average of the kept samples is a little better than the first
# triplet alone, close to the paper's own figure, and the L2 mean of the same samples is
# about as good: the registered and filtered samples hold no gross outliers, so the two
# averages nearly coincide here.
#
# ## The recording
#
# The recording of the noisy synthetic run puts the rotation samples in the largest view:
# per frame, each triplet's registered camera axes (`/rotations/triplet_k`, thin; grey
# where the filter dropped the sample), their L1 average (`/rotations/averaged`, thicker) and
# the ground truth (`/rotations/ground_truth`, pale, longest). A few degrees are hard to see on
# axes of length one, so a second view zooms in, as the first figure did: per frame, the
# samples and the average as rotation vectors relative to the truth, in degrees, with a
# sphere of 5 degrees around the truth for scale (`/lesson/tangent/...`). The third view is
# the per-frame e_R of each triplet's samples and of their average (`/lesson/e_R/...`).

# %%
import rerun as rr
import rerun.blueprint as rrb

eye = rrb.EyeControls3D(position=[1.3, -1.55, 1.05], look_target=[0, 0, 0.2], eye_up=[0, 0, 1])
zoom = rrb.EyeControls3D(position=[7.5, -9, 6], look_target=[0, 0, 0], eye_up=[0, 0, 1])
thinner = {  # thinner arrows for the average and the truth, so the samples show beside them
    "/rotations/averaged": rr.Arrows3D.from_fields(radii=0.008),
    "/rotations/ground_truth": rr.Arrows3D.from_fields(radii=0.012),
}
axes = "camera axes: samples (thinnest), L1 average, ground truth (pale, longest)"
zoomed = "seen from the truth (deg): samples (grey, red if dropped), average (orange)"
layout = rrb.Blueprint(
    rrb.Horizontal(
        rrb.Spatial3DView(origin="/rotations", name=axes, eye_controls=eye, overrides=thinner),
        rrb.Vertical(
            rrb.Spatial3DView(origin="/lesson/tangent", name=zoomed, eye_controls=zoom),
            rrb.TimeSeriesView(origin="/lesson/e_R", name="e_R per frame: samples, average"),
        ),
        column_shares=[3, 2],
    ),
    rrb.TimePanel(state="collapsed", timeline="frame"),
    collapse_panels=True,
)

# %% [markdown]
# The zoomed view and the per-frame e_R are not part of a reconstruction's recording: the
# lesson logs them in a function that `save_recording` calls with the open stream. The
# recording shows the rotations aligned to the truth (`recording_content` holds them so).

# %%
content = recording_content(result, seq)
truth_shown = content.rotations_gt_display


def tangent_deg(R):  # rotation vectors of R (F, 3, 3) relative to the truth, degrees
    return np.rad2deg(Rotation.from_matrix(R @ truth_shown.transpose(0, 2, 1)).as_rotvec())


samples_deg = np.stack([tangent_deg(R) for R in content.triplet_rotations], axis=1)
grey_or_red = np.where(content.triplet_kept.T[..., None], [110, 110, 110, 255], [230, 60, 60, 255])
per_frame = {f"triplet_{k + 1}": rs.registered[k] for k in range(seq.K)}
per_frame["averaged"] = rs.averaged
errors_per_frame = {
    name: nrsfm.rotation_error(resolve_depth_signs(R)[0], seq.rotations, per_frame=True)
    for name, R in per_frame.items()
}
largest = np.linalg.norm(samples_deg, axis=2).max()
ring_deg = 5.0  # a sphere around the truth, for scale
print(f"largest angle of a sample from the truth {largest:.1f} deg; sphere of {ring_deg:.0f} deg")


# %%
def log_lesson(rec):
    frames = [rr.TimeColumn("frame", sequence=np.arange(seq.n_frames))]
    points = rr.Points3D.columns(
        positions=samples_deg.reshape(-1, 3), colors=grey_or_red.reshape(-1, 4).astype(np.uint8)
    )
    rec.send_columns("/lesson/tangent/samples", frames, points.partition([seq.K] * seq.n_frames))
    rec.log("/lesson/tangent/samples", rr.Points3D.from_fields(radii=[0.4]), static=True)
    average = rr.Points3D.columns(positions=tangent_deg(content.averaged))
    rec.send_columns("/lesson/tangent/averaged", frames, average)
    style = rr.Points3D.from_fields(radii=[0.5], colors=[(255, 140, 0, 255)])
    rec.log("/lesson/tangent/averaged", style, static=True)
    truth_dot = rr.Points3D([[0, 0, 0]], radii=[0.5], colors=[(70, 130, 255, 255)])
    rec.log("/lesson/tangent/ground_truth", truth_dot, static=True)
    kw = dict(colors=[(70, 130, 255, 255)], line_radii=[0.03], fill_mode="majorwireframe")
    ring = rr.Ellipsoids3D(radii=[ring_deg], **kw)
    rec.log("/lesson/tangent/ground_truth/sphere", ring, static=True)
    for name, err in errors_per_frame.items():
        rec.send_columns(f"/lesson/e_R/{name}", frames, rr.Scalars.columns(scalars=err))


rrd = output_path("04_rotation_averaging.rrd")
save_recording(result, rrd, seq, blueprint=layout, extra=log_lesson)
print(f"wrote {shown_path(rrd)} ({rrd.stat().st_size / 1e6:.2f} MB)")
show_recording(rrd)

# %% [markdown]
# ![The recording in the Rerun web viewer](../docs/notebooks/recordings/04_rotation_averaging.png)
#
# In the viewer, play the frame timeline. On the left, the thin axes of the three triplets
# stay bundled with the average, and the pale ground truth is a little apart. On the top
# right, the same zoomed in: the samples (grey) stay in a tight group with the average
# (orange) among them, a few degrees from the truth (blue, at the centre): the error they
# share. The e_R curves of the samples and of the average run together.
#
# ## Summary
#
# - Single rotation averaging (Eq. 4) finds the rotation closest to a frame's samples. With
#   the chordal distance and squares (L2) it is the projection of the mean matrix onto
#   SO(3), in closed form.
# - The L1 average (Eq. 5) minimises the sum of geodesic angles; Algorithm 1 starts from the
#   element-wise median projected onto SO(3) (Eq. 6) and takes Weiszfeld steps: a mean of
#   the samples' rotation vectors weighted by one over their length, applied with the
#   exponential map. `nrsfm.geometry.average_rotations` is that loop for all frames.
# - Far-off samples drag the L2 mean in proportion to their share; the L1 average gives
#   them little weight and stays near the noise level up to a quarter of outliers.
# - In the pipeline the samples share the error of the noisy motion factor: their average
#   is no better than the best triplet (`organic` and `bmm` are within a few per cent).
#
# ## Exercises
#
# 1. Start the Weiszfeld loop of the first frame from the L2 mean instead of the median.
#    Does it reach the same average?
# 2. In the first frame, move more of the twelve samples to the far side (four, five, six,
#    seven). From how many on does the L1 average follow them?
# 3. What is the largest chordal distance between two rotations, and for which angle?
#
# <details><summary>Answers</summary>
#
# - To 1: yes, to well below a degree: the L1 cost has one minimum here, and both starts
#   lead to it (the median is the paper's choice because it is already near it when there
#   are outliers).
# - To 2: while the far samples are fewer than half, the L1 average stays near the truth
#   (pulled a few degrees more by each one); at six against six it lands between the two
#   groups; from seven on it follows the far group. Like a median, it goes with the
#   majority; the L2 mean moves steadily with every far sample.
# - To 3: $2\sqrt2$, for a half turn (an angle of $\pi$), where $\sin(d_\angle/2)=1$.
#
# </details>

# %% tags=["answers"]
L1_from_L2, _, _ = weiszfeld(S, L2)
assert np.rad2deg(rotation_angle(L1_from_L2, L1)) < 0.1
side, side_L2 = {}, {}
for n in (3, 4, 5, 6, 7):
    rv = np.deg2rad(jitter_deg) * np.random.default_rng(4).standard_normal((m, 3))
    rv[:n] += np.deg2rad(far_deg) * far_axis
    S_n = Rotation.from_rotvec(rv).as_matrix() @ R_true
    side[n] = deg_from_truth(average_rotations(S_n[:, None])[0])
    side_L2[n] = deg_from_truth(project_to_so3(S_n.mean(axis=0)))
assert side[3] < side[4] < side[5] < 10 < side[6] < 30 < side[7], side
assert np.all(np.diff(list(side_L2.values())) > 2), side_L2
half_turn = Rotation.from_rotvec([np.pi, 0, 0]).as_matrix()
assert abs(np.linalg.norm(half_turn - np.eye(3)) - 2 * np.sqrt(2)) < 1e-12

# %% tags=["checks"]
# What the prose above says, checked on every run (CI).
d_L2, d_L1, d_start = deg_from_truth(L2), deg_from_truth(L1), deg_from_truth(R_o)
assert d_L2_lib > 3 * d_L1_lib and d_L2 > 4 and gap_chord < 1e-12 and gap_angle < 1e-9
random_angle = rotation_angle(Rotation.random(2000, random_state=0).as_matrix(), np.eye(3))
assert cost_L2 <= costs.min() and random_angle.mean() > np.pi / 2  # "more than a right angle"
assert np.all(np.linalg.svd(R_bar)[1] < 1) and np.abs(L2 - project_to_so3(R_bar)).max() < 1e-12
assert np.linalg.svd(S_o)[1].min() < 0.99 and np.abs(R_o - start_lib).max() < 1e-12
assert d_start < 0.5 * d_L2 and d_L1 < 0.3 * d_L2 and weights[:n_far].sum() < 0.1
assert np.all(np.diff(cost) < 0) and cost.size <= 6  # falls every step, a few steps
assert gap_L1 < 1e-6 and info_one["iterations"][0] == cost.size
assert all(rotation_angle(S, L1).sum() < rotation_angle(S, R).sum() for R in (R_o, L2))
for frac, _, e_L1, e_L2, steps, conv in table:  # L1 lowest with outliers; converged
    assert (e_L1 < e_L2 or frac == 0.0) and conv and steps < 10, frac
assert by[0.0][2] < by[0.0][1] / 2.5 and by[0.0][3] < by[0.0][2]  # "about three times"
assert by[0.25][2] < 1.6 * by[0.0][2] and by[0.5][2] < 0.4 * by[0.5][3]
assert np.all(np.diff([row[3] for row in table]) > 0) and by[0.1][1] > 10
assert same and np.abs(averaged - rs.averaged).max() < 1e-12
assert 0.8 * kept.size < kept.sum() < kept.size  # "drops a few"
errs, e_L2_all = [e_R(r) for r in rs.registered], e_R(project_to_so3(rs.registered.mean(0)))
assert min(errs) < e_R(averaged) < max(errs) and abs(e_L2_all - e_R(averaged)) < 0.01
assert 0.35 < apart / (np.sqrt(2) * e_one) < 0.65  # "about half as far"
assert np.all(np.abs(rows_noise[:, 1] / rows_noise[:, 0] - 1) < 0.06) and abs(ratio - 1) < 0.06
if HAVE_DATA:
    L1p, L2p = pick["L1 average, kept samples"], pick["L2 mean, kept samples"]
    assert L1p < pick["triplet 1 alone"] and max(abs(L1p - L2p), abs(L1p - paper["ours"])) < 3e-3

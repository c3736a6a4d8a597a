# %% [markdown]
# # 01 · The measurement matrix and its rank-3K factorisation
#
# **What you will learn**
#
# - how the 2D tracks of a deforming object are stacked into the measurement matrix W,
#   and why subtracting each row's mean removes the camera's translation;
# - why W has rank at most 3K when the shape mixes K basis shapes, and how the SVD finds
#   the 3K directions it spans;
# - why those directions do not give the cameras yet (the corrective matrix G of the next
#   lesson), and how noise shows in the singular values.
#
# **Prerequisites**: notebook 00 (what the method computes); the singular value
# decomposition and the rank of a matrix (`numpy.linalg.svd`).
#
# **Paper**: Sec. 2 (the problem), Eq. (1).
#
# ## The idea
#
# A camera films P points on an object that bends. Write down where each point appears in
# each frame: two numbers (x, y) per point per frame. Stack them, two rows per frame and one
# column per point, and you have W. If the object's shape at any moment is a mix of a few
# basis shapes, every row of W is a mix of a few fixed rows, so W is a very thin matrix in
# disguise: a tall factor times a wide one. The SVD finds that thin structure.
#
# The picture first: a synthetic object (its ground truth known), the tracks of its points
# as the camera turns, and W drawn as an image.

# %%
import os

for _v in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_v, "1")

import matplotlib.pyplot as plt
import numpy as np
from scipy.linalg import subspace_angles

import data_tools
import nrsfm
from nrsfm import paths
from nrsfm.stages.measurement import centre_rows, factorize
from nrsfm.views import figures, output_path, save_recording, show_recording, shown_path

# %%
seq = data_tools.make_synthetic(F=150, P=45, K=3, motion="smooth", seed=7)
F, P, K = seq.n_frames, seq.n_points, seq.K
W = seq.W
print(f"F = {F} frames, P = {P} points, K = {K} basis shapes; W is {W.shape[0]} x {W.shape[1]}")

fig, (ax1, ax2) = plt.subplots(1, 2, figsize=(10, 3.6))
for p in range(0, P, 4):  # every fourth point's path through the image
    ax1.plot(W[0::2, p], W[1::2, p], lw=0.8)
ax1.scatter(W[0], W[1], s=8, c="k", label="frame 0")
ax1.set(title="tracks in the image", xlabel="x", ylabel="y", aspect="equal")
ax1.legend(loc="lower right")
im = ax2.imshow(W, aspect="auto", cmap="RdBu_r")
ax2.set(title="W: rows x_f, y_f; one column per point", xlabel="point", ylabel="row")
fig.colorbar(im, ax=ax2)
plt.show()

# %% [markdown]
# Each coloured curve is one point moving through the image over the frames; the black dots
# are the first frame. On the right, the same numbers as a matrix: two rows per frame (x then
# y), one column per point. Nothing in W says which depth a point had: that is what the
# method recovers.
#
# ## Why W has rank at most 3K (Eq. 1)
#
# The shape of frame f mixes K basis shapes $\mathbf B_k$ (each 3 x P) with weights
# $c_{fk}$, and an orthographic camera keeps two rows of a rotation,
# $\mathbf R_f\in\mathbb R^{2\times3}$ with orthonormal rows. Frame f's two rows of W are
# $\mathbf W_f=\mathbf R_f\sum_k c_{fk}\mathbf B_k$, so for all frames
#
# $$\mathbf W=\underbrace{\begin{bmatrix}c_{11}\mathbf R_1&\cdots&c_{1K}\mathbf R_1\\
#   \vdots&&\vdots\\ c_{F1}\mathbf R_F&\cdots&c_{FK}\mathbf R_F\end{bmatrix}}_{\mathbf M:\
#   2F\times3K}\underbrace{\begin{bmatrix}\mathbf B_1\\ \vdots\\
#   \mathbf B_K\end{bmatrix}}_{\mathbf B:\ 3K\times P}.\qquad(1)$$
#
# A product through 3K columns has rank at most 3K. We build M and B from the ground truth
# with numpy and multiply them back.

# %%
C, R = seq.extra["coefficients"], seq.rotations  # c_fk (F, K), R_f (F, 3, 3)
M_true = np.concatenate([C[:, k, None, None] * R[:, :2] for k in range(K)], axis=2)
M_true = M_true.reshape(2 * F, 3 * K)  # row block f: [c_f1 R_f, ..., c_fK R_f]
B_true = seq.extra["basis"].reshape(3 * K, P)  # the K basis shapes stacked
print(f"M is {M_true.shape}, B is {B_true.shape}")
print(f"max |M B - W| = {np.abs(M_true @ B_true - W).max():.1e}")

# %% [markdown]
# M times B gives W back to rounding error: W really is a 300 x 9 matrix times a 9 x 45 one.
#
# ## Centring removes the translation
#
# A real camera also shifts the image: frame f adds a translation $\mathbf t_f$ to every
# point of the frame. That adds the same number to a whole row of W, so subtracting each
# row's mean removes it (the paper assumes centred W; the library does it first).

# %%
rng = np.random.default_rng(0)
shift = np.repeat(rng.normal(0, 5, F), 2).reshape(2 * F, 1)  # one offset per frame row
W_shifted = W + shift
W_centred = W_shifted - W_shifted.mean(axis=1, keepdims=True)  # by hand
W_lib, row_means = centre_rows(W_shifted)  # the library's stage
print(f"max |centred by hand - W| = {np.abs(W_centred - W).max():.1e}")
print(f"max |centre_rows - by hand| = {np.abs(W_lib - W_centred).max():.1e}")

# %% [markdown]
# Both differences are at rounding level: the translation is gone, and the library's
# `centre_rows` is exactly the one-line numpy version (the synthetic W was centred already,
# so centring it again gives it back).
#
# ## The SVD finds the 3K directions
#
# The singular values of W count its independent directions: exactly 3K of them are not
# zero. Keeping those, $\mathbf W=\mathbf U_{3K}\mathbf S_{3K}\mathbf V_{3K}^\top$, and
# splitting $\mathbf S$ evenly gives $\hat{\mathbf M}=\mathbf U_{3K}\mathbf S_{3K}^{1/2}$
# (2F x 3K) and $\hat{\mathbf B}=\mathbf S_{3K}^{1/2}\mathbf V_{3K}^\top$ (3K x P).

# %%
# NBVAL_CHECK_OUTPUT
U, s, Vt = np.linalg.svd(W, full_matrices=False)
M_hat = U[:, : 3 * K] * np.sqrt(s[: 3 * K])
B_hat = np.sqrt(s[: 3 * K])[:, None] * Vt[: 3 * K]
print("singular values 1-11 / sigma_1:", np.array2string(s[:11] / s[0], precision=2))
print(f"max |M_hat B_hat - W| = {np.abs(M_hat @ B_hat - W).max():.0e}")
fact = factorize(W, K)  # the library's stage: the same numbers
print(f"factorize: same singular values: {np.allclose(fact.singular_values, s)}")

# %% [markdown]
# Nine values (3K with K = 3) are of order one and the tenth is at rounding level: the
# rank is 3K. The rank-3K factors reproduce W, and the library's `factorize` returns the
# same singular values (its `M_hat` and `B_hat` are these factors).

# %%
figures.singular_values_figure(s, mark=3 * K, title="noise-free W: exactly 3K non-zero")
plt.show()

# %% [markdown]
# On a log scale the gap after the ninth singular value spans more than ten decades.
#
# ## The right directions, not yet the cameras
#
# $\hat{\mathbf M}$ spans the same column space as the true M: the principal angles between
# the two spaces (`scipy.linalg.subspace_angles`) are zero. But for any invertible 3K x 3K
# matrix G, $(\hat{\mathbf M}\mathbf G)(\mathbf G^{-1}\hat{\mathbf B})$ is W as well, so W
# alone cannot choose between them.

# %%
angles = np.rad2deg(subspace_angles(M_true, M_hat))
print(f"largest principal angle between M and M_hat: {angles.max():.0e} degrees")
G = rng.standard_normal((3 * K, 3 * K))
W_again = (M_hat @ G) @ (np.linalg.inv(G) @ B_hat)
print(f"max |W - (M_hat G)(G^-1 B_hat)| = {np.abs(W_again - W).max():.0e}")

# %% [markdown]
# The angle is zero to rounding and a random G fits W just as well. What singles out the
# right G is the form of M: in every frame, each column triplet holds a scaled rotation
# $c_{fk}\mathbf R_f$, whose two rows have equal length and are orthogonal. A triplet of
# $\hat{\mathbf M}$ does not have that form; the true one does:


# %%
def orthonormality_violation(M3):
    """Per frame: (| |r1|^2 - |r2|^2 | + 2 |r1.r2|) / (|r1|^2 + |r2|^2); 0 for a scaled rotation."""
    r = M3.reshape(-1, 2, 3)
    n1, n2 = (r[:, 0] ** 2).sum(1), (r[:, 1] ** 2).sum(1)
    return (np.abs(n1 - n2) + 2 * np.abs((r[:, 0] * r[:, 1]).sum(1))) / (n1 + n2)


v_svd = orthonormality_violation(M_hat[:, :3]).mean()
v_true = orthonormality_violation(M_true[:, :3]).mean()
print(f"mean violation: first triplet of M_hat {v_svd:.2f}, of the true M {v_true:.0e}")

# %% [markdown]
# The SVD's first triplet is far from a scaled rotation (its violation is far from
# zero), the true triplet is one to rounding. Finding a G whose triplets restore that
# form is lesson 02.
#
# ## With noise the spectrum tells the rank
#
# Real tracks are noisy. Noise of standard deviation $\sigma$ (here a fraction of W's typical
# spread) fills every singular value a little, so the rank-3K fit leaves a residual, and the
# fitted directions tilt. We measure three things: the residual of the rank-3K fit relative
# to W, the ratio $\sigma_{3K}/\sigma_{3K+1}$ (the gap), and the largest principal angle.

# %%
# NBVAL_CHECK_OUTPUT
spectra, rows = [], []
for noise in (0.0, 0.01, 0.05):
    noisy = data_tools.make_synthetic(F=150, P=45, K=3, noise=noise, seed=7)
    f_n = factorize(noisy.W, K)
    sv = f_n.singular_values
    gap = sv[3 * K - 1] / max(sv[3 * K], 1e-300)
    angle = np.rad2deg(subspace_angles(M_true, f_n.M_hat)).max()
    spectra.append(sv)
    rows.append((noise, f_n.residual, gap, angle))
    ratio = f"{f_n.residual / noise:.2f}" if noise else "-"
    print(
        f"noise {noise:4.2f}: residual {f_n.residual:.3f} (ratio to noise {ratio}), "
        f"gap {gap:.3g}, largest angle {angle:.1f} deg"
    )

# %% [markdown]
# Without noise the residual is zero and the gap is enormous. With noise, the residual is a
# little below the noise level (ratio about 0.86: the 3K fitted directions absorb some of the
# noise), the gap shrinks but stays above one, and the fitted directions tilt, most in the
# weakest of the 3K directions: the angle grows with the noise. The rank is still readable:

# %%
labels = [f"noise {r[0]}" for r in rows]
figures.singular_values_figure(spectra, labels, mark=3 * K, title="singular values with noise")
plt.show()

# %% [markdown]
# ## Real motion capture (when `NRSFM_DATA` is set)
#
# `NRSFM_DATA` names the folder that holds `mocap/` (the README says where the data come
# from). A real body is not exactly a mix of K shapes: its spectrum decays with no clean
# gap, and the K the paper uses per sequence is a modelling choice.

# %%
MOCAP = paths.data_dir() / "mocap" if os.environ.get("NRSFM_DATA") else None
if MOCAP is not None and (MOCAP / "pickup.mat").is_file():
    pickup = data_tools.load_mocap("pickup", data_dir=MOCAP)
    f_m = factorize(pickup.W, pickup.K)
    sm = np.linalg.svd(pickup.W - pickup.W.mean(1, keepdims=True), compute_uv=False)
    print(f"pickup: F = {pickup.n_frames}, P = {pickup.n_points}, the paper's K = {pickup.K}")
    k3 = 3 * pickup.K
    print(
        f"rank-{k3} residual {f_m.residual:.5f}, gap sigma_3K/sigma_3K+1 {sm[k3 - 1] / sm[k3]:.2f}"
    )
    figures.singular_values_figure(sm, mark=3 * pickup.K, title="pickup: singular values")
    plt.show()
else:
    print("no MoCap data (set NRSFM_DATA to the folder holding mocap/): this part skipped")

# %% [markdown]
# With the data, pickup's singular values fall smoothly past the mark at 3K: the gap is
# close to one, so nothing in the spectrum says "3K" (the paper's K is a choice). The rank-3K
# fit still leaves only a small residual, the part of the motion the model with the paper's
# K does not capture.
#
# ## The recording
#
# The Rerun recording of this lesson shows the measured tracks (`/image/measured`) beside
# the re-projection of a reconstruction (`/image/reprojected`), and the spectrum of W as bars
# of $\log_{10}\sigma_i/\sigma_1$ (`/lesson/log10_singular_values`): the drop after bar 9
# is the rank. The reconstruction is given the true cameras (finding them is the next
# three lessons); its shape stage is lesson 05's.

# %%
import rerun.blueprint as rrb

layout = rrb.Blueprint(
    rrb.Horizontal(
        rrb.Spatial2DView(origin="/image", name="W_f: measured tracks and re-projection"),
        rrb.Vertical(
            rrb.BarChartView(origin="/lesson/log10_singular_values", name="log10 s_i / s_1"),
            rrb.TextDocumentView(origin="/run/report", name="report"),
        ),
        column_shares=[3, 2],
    ),
    rrb.TimePanel(state="collapsed", timeline="frame"),
    collapse_panels=True,
)

# %% [markdown]
# The layout gives the image the most room, the spectrum and the run's report beside it.
# The spectrum is not part of a reconstruction's recording: the lesson logs it itself, in
# a function that `save_recording` calls with the open stream.


# %%
def log_spectrum(rec):
    import rerun as rr

    rec.log("/lesson/log10_singular_values", rr.BarChart(np.log10(s / s[0] + 1e-17)), static=True)


result = nrsfm.reconstruct(W, K, rotations=seq.rotations)  # the true cameras
rrd = output_path("01_measurement_svd.rrd")
save_recording(result, rrd, seq, blueprint=layout, extra=log_spectrum)
print(f"wrote {shown_path(rrd)} ({rrd.stat().st_size / 1e6:.2f} MB)")
show_recording(rrd)

# %% [markdown]
# ![The recording in the Rerun web viewer](../docs/notebooks/recordings/01_measurement_svd.png)
#
# In the viewer, play the frame timeline: the measured points (W_f) and their re-projection
# coincide, and the bar chart's cliff after the ninth bar is the rank 3K.
#
# ## Summary
#
# - W stacks the tracks: two rows per frame, one column per point; centring its rows
#   removes the camera's translation.
# - With K basis shapes, W = M B through 3K columns (Eq. 1): rank at most 3K, and the SVD's
#   first 3K singular vectors span M's columns.
# - The SVD's factors are right only up to an invertible G: the cameras need the form of M
#   (a scaled rotation in every triplet), the subject of lesson 02.
# - Noise fills the trailing singular values; the gap after 3K shrinks but shows the rank.
#
# ## Exercises
#
# 1. Make the same sequence with K = 2 (`make_synthetic(F=150, P=45, K=2, seed=7)`). How
#    many singular values are not zero?
# 2. Translate only the x rows of W by a constant per frame. Does centring still remove it?
#    What if every point moved by its own amount?
# 3. Show that $\hat{\mathbf M}\mathbf G$ for an orthogonal 3K x 3K matrix G still spans the
#    same column space as M (compute the principal angles).
#
# <details><summary>Answers</summary>
#
# - To 1: six, the rank is 3K.
# - To 2: yes for a constant per row (the row mean takes it); no for a shift per point,
#   which changes the shape, not the frame.
# - To 3: the angles are zero: any invertible G keeps the column space, which is why the
#   SVD cannot choose G.
#
# </details>

# %% tags=["answers"]
s2 = np.linalg.svd(data_tools.make_synthetic(F=150, P=45, K=2, seed=7).W, compute_uv=False)
assert np.sum(s2 > 1e-9 * s2[0]) == 6
x_shift = W.copy()
x_shift[0::2] += rng.normal(0, 3, (F, 1))
assert np.allclose(centre_rows(x_shift)[0], W, atol=1e-9)
per_point = W + rng.normal(0, 1, (1, P))
assert not np.allclose(centre_rows(per_point)[0], W, atol=1e-3)
Q, _ = np.linalg.qr(rng.standard_normal((3 * K, 3 * K)))
assert np.rad2deg(subspace_angles(M_true, M_hat @ Q)).max() < 1e-6

# %% tags=["checks"]
# What the prose above says, checked on every run (CI).
assert np.abs(M_true @ B_true - W).max() < 1e-9
assert np.abs(W_centred - W).max() < 1e-9 and np.abs(W_lib - W_centred).max() < 1e-12
assert s[3 * K] / s[0] < 1e-12 < s[3 * K - 1] / s[0]  # rank exactly 3K
assert s[3 * K - 1] / s[3 * K] > 1e10  # the gap spans more than ten decades
assert np.allclose(fact.singular_values, s, rtol=1e-10, atol=1e-12 * s[0])
assert angles.max() < 1e-6 and np.abs(W_again - W).max() < 1e-8
assert 0.1 < v_svd < 1 and v_true < 1e-12
for noise, residual, gap, angle in rows[1:]:
    assert 0.8 < residual / noise < 0.9 and gap > 1  # "about 0.86", "stays above one"
assert rows[1][3] < rows[2][3]  # the angle grows with the noise
if MOCAP is not None and (MOCAP / "pickup.mat").is_file():
    assert f_m.residual < 1e-3 and sm[k3 - 1] / sm[k3] < 1.5  # "small", "close to one"

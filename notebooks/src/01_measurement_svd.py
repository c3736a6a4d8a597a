# %% [markdown]
# # 01 · The measurement matrix and its rank-3K factorisation
#
# Paper Sec. 2, **Eq. (1)**. With $\mathbf X_f=\sum_{k=1}^K c_{fk}\mathbf B_k$ and an
# orthographic camera $\mathbf R_f\in\mathbb R^{2\times3}$ (two orthonormal rows),
#
# $$\mathbf W=\begin{bmatrix}c_{11}\mathbf R_1&\cdots&c_{1K}\mathbf R_1\\ \vdots&&\vdots\\
#   c_{F1}\mathbf R_F&\cdots&c_{FK}\mathbf R_F\end{bmatrix}
#   \begin{bmatrix}\mathbf B_1\\ \vdots\\ \mathbf B_K\end{bmatrix}=\mathbf M\mathbf B,\qquad
#   \mathbf M\in\mathbb R^{2F\times3K},\ \mathbf B\in\mathbb R^{3K\times P},$$
#
# so $\operatorname{rank}\mathbf W\le 3K$. The truncated SVD
# $\mathbf W\approx\mathbf U_{3K}\mathbf S_{3K}\mathbf V_{3K}^\top$ gives
# $\hat{\mathbf M}=\mathbf U_{3K}\mathbf S_{3K}^{1/2}$ and
# $\hat{\mathbf B}=\mathbf S_{3K}^{1/2}\mathbf V_{3K}^\top$: the right column space, but only
# up to an invertible **corrective matrix** $\mathbf G\in\mathbb R^{3K\times3K}$,
# $\mathbf W=(\hat{\mathbf M}\mathbf G)(\mathbf G^{-1}\hat{\mathbf B})$. Finding (the column
# triplets of) $\mathbf G$ is notebook 02.
#
# Here: `nrsfm.stages.measurement.centre_rows` and `nrsfm.stages.measurement.factorize` on synthetic data
# whose $\mathbf M$ is known, with and without noise, and on MoCap data if available.

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

# %% [markdown]
# ## Centring removes the translation
#
# An orthographic projection adds a per-frame image translation $\mathbf t_f$ to every point.
# Subtracting each row's mean removes it exactly (the shapes are then centred too).

# %%
seq = data_tools.make_synthetic(F=150, P=45, K=3, motion="smooth", seed=7)
F, P, K = seq.n_frames, seq.n_points, seq.K
rng = np.random.default_rng(0)
W_shifted = seq.W + np.repeat(rng.normal(0, 5, (F, 2)), 1, axis=0).reshape(2 * F, 1)
Wc, means = centre_rows(W_shifted)
print("max |centred - W| =", np.abs(Wc - seq.W).max())
assert np.allclose(Wc, seq.W, atol=1e-12)

# %% [markdown]
# ## Noise-free: rank exactly 3K, and the right column space
#
# The true $\mathbf M$ is built from the ground truth: row block $f$ is
# $[c_{f1}\mathbf R_f,\dots,c_{fK}\mathbf R_f]$. Its column space must equal
# $\hat{\mathbf M}$'s: the principal angles between them are zero.

# %%
fact = factorize(seq.W, K)
s = fact.singular_values
C, R = seq.extra["coefficients"], seq.rotations
M_true = np.concatenate([C[:, k, None, None] * R[:, :2] for k in range(K)], axis=2).reshape(
    2 * F, 3 * K
)
angles = np.rad2deg(subspace_angles(M_true, fact.M_hat))
print("singular values:", np.round(s[: 3 * K + 2], 4))
print(
    f"sigma_3K+1 / sigma_1 = {s[3 * K] / s[0]:.1e}, residual {fact.residual:.1e}, "
    f"largest principal angle {angles.max():.1e} deg"
)
assert fact.M_hat.shape == (2 * F, 3 * K) and fact.B_hat.shape == (3 * K, P)
assert s[3 * K] / s[0] < 1e-12 and fact.residual < 1e-12  # measured ~1e-16
assert angles.max() < 1e-8  # measured ~1e-13 deg
figures.singular_values_figure(s, mark=3 * K, title="noise-free W: exactly 3K = 9 non-zero")
plt.show()

# %% [markdown]
# ## The ambiguity: any invertible G fits W equally well
#
# $\hat{\mathbf M}\mathbf G$ reproduces $\mathbf W$ for every invertible $\mathbf G$, so the SVD
# alone cannot know the rotations. What singles out the right $\mathbf G$ is the structure of
# $\mathbf M$: each $2\times3$ block of a column triplet is a scaled rotation $c_{fk}\mathbf R_f$
# (equal row norms, orthogonal rows; the constraints of notebook 02). The SVD's own first
# triplet does not have it; the true one does.

# %%
G = rng.standard_normal((3 * K, 3 * K))
W_again = (fact.M_hat @ G) @ (np.linalg.inv(G) @ fact.B_hat)
print("max |W - (M G)(G^-1 B)| =", np.abs(W_again - seq.W).max())
assert np.allclose(W_again, seq.W, atol=1e-9)


def orthonormality_violation(M3):
    """Per frame: | |r1|^2 - |r2|^2 | + 2 |r1.r2|, relative to |r1|^2 + |r2|^2."""
    B = M3.reshape(F, 2, 3)
    n1, n2 = (B[:, 0] ** 2).sum(1), (B[:, 1] ** 2).sum(1)
    return (np.abs(n1 - n2) + 2 * np.abs((B[:, 0] * B[:, 1]).sum(1))) / (n1 + n2)


v_svd = orthonormality_violation(fact.M_hat[:, :3]).mean()
v_true = orthonormality_violation(M_true[:, :3]).mean()
print(f"mean violation: SVD triplet {v_svd:.3f}, true triplet {v_true:.1e}")
assert v_true < 1e-12 and v_svd > 0.05

# %% [markdown]
# ## With noise: the spectrum tells the rank
#
# Gaussian noise of standard deviation $\sigma$ (a fraction of W's mean row std) fills the
# trailing singular values. The relative residual of the rank-$3K$ fit is the part of the
# noise outside the fitted subspace: a bit below $\sigma$ (the fitted $3K$ directions absorb
# some of it). The column space tilts by a few degrees in its weakest directions.

# %%
rows = []
spectra = []
for noise in (0.0, 0.01, 0.05):
    s_n = data_tools.make_synthetic(F=150, P=45, K=3, noise=noise, seed=7)
    f_n = factorize(s_n.W, K)
    ang = np.rad2deg(subspace_angles(M_true, f_n.M_hat)).max()
    gap = f_n.singular_values[3 * K - 1] / max(f_n.singular_values[3 * K], 1e-300)
    rows.append((noise, f_n.residual, gap, ang))
    spectra.append(f_n.singular_values)
    print(
        f"noise {noise:4.2f}: residual {f_n.residual:.4f}  sigma_3K/sigma_3K+1 {gap:9.3g}  "
        f"max angle {ang:6.2f} deg"
    )
for noise, res, gap, ang in rows[1:]:
    assert 0.5 * noise < res < noise  # measured 0.86 and 0.86 x noise
assert rows[1][2] > 5 and rows[2][2] > 1.5  # the 3K gap survives (measured 9.7, 2.1)
figures.singular_values_figure(
    spectra, [f"noise {r[0]}" for r in rows], mark=3 * K, title="singular values of W with noise"
)
plt.show()

# %% [markdown]
# ## MoCap data (when `NRSFM_DATA` is set)
#
# `NRSFM_DATA` names the folder that holds `mocap/`; a relative path is taken from the
# folder Jupyter (or the shell) was started in, not from this notebook's folder
# (`nrsfm.paths.data_dir`).
#
# Real motion capture is not exactly low rank: the spectrum decays without a clean gap at
# $3K$ (the paper's $K$ per sequence is a modelling choice, `data_tools.MOCAP_K`).

# %%
mocap = None
MOCAP = paths.data_dir() / "mocap" if os.environ.get("NRSFM_DATA") else None
if MOCAP is not None and (MOCAP / "pickup.mat").is_file():
    mocap = data_tools.load_mocap("pickup", data_dir=MOCAP)
    f_m = factorize(mocap.W, mocap.K)
    sm = f_m.singular_values
    print(
        f"{mocap}: rank-{3 * mocap.K} residual {f_m.residual:.4f}, "
        f"sigma_3K+1/sigma_1 {sm[3 * mocap.K] / sm[0]:.2e}"
    )
    assert 1e-4 < f_m.residual < 0.2
    figures.singular_values_figure(sm, mark=3 * mocap.K, title="pickup: singular values of W")
    plt.show()
else:
    print("no MoCap data (set NRSFM_DATA to the folder holding mocap/): MoCap part skipped")

# %% [markdown]
# ## Recording
#
# The rank-$K$ pseudo-inverse reconstruction with the ground-truth cameras, recorded with the
# singular values of $\mathbf W$ and of $\mathbf X_{init}^\sharp$ as bar charts
# (`/singular_values/W`, `/singular_values/X_init`) next to the tracks
# (`/image/measured`) and shapes.

# %%
result = nrsfm.reconstruct(seq.W, K, method="pseudo_inverse", rotations=seq.rotations)
assert np.allclose(result.factorization.singular_values * result.scale, s, rtol=1e-9)
rrd = save_recording(result, output_path("01_measurement_svd.rrd"), seq)
print(f"wrote {shown_path(rrd)} ({rrd.stat().st_size / 1e6:.2f} MB)")
show_recording(rrd)

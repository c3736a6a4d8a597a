# %% [markdown]
# # 02 · Corrective triplets: Dai's constraints on $\mathbf Q^k=\mathbf G^k\mathbf G^{k\top}$
#
# **What you will learn**
#
# - why a column triplet $\mathbf G^k$ of the corrective matrix must turn every frame's
#   block of $\hat{\mathbf M}$ into a scaled rotation, and how that gives two linear
#   equations per frame on its Gram matrix $\mathbf Q^k=\mathbf G^k\mathbf G^{k\top}$
#   (Dai et al.);
# - why those equations leave a whole space of solutions, of dimension $2K^2-K$, and how a
#   convex relaxation picks a point of it whose top three eigenvectors give a triplet, which
#   a refinement of Dai's cost then makes exact;
# - why noise gives Dai's cost several minima, and how the library's triplet search
#   (relaxations, then seeded random starts, stopped once the best minimum is found twice)
#   finds the good one.
#
# **Prerequisites**: lesson 01 ($\mathbf W\approx\hat{\mathbf M}\hat{\mathbf B}$ is right
# only up to an invertible $\mathbf G$); least squares, the null space of a matrix from its
# SVD, the eigen-decomposition of a symmetric matrix, positive semi-definite (PSD) matrices.
#
# **Paper**: Sec. 2 (a) and Sec. 3.1 (every $\mathbf G^k$ "using Dai et al."), Fig. 1 (a)-(b),
# Eq. (1). The constraints and the cost are Dai, Li and He's (CVPR 2012); the paper does
# not say how it gets K different triplets (lesson 03 shows the library's answer).
#
# ## The idea
#
# Eq. (1) says that the true motion matrix $\mathbf M=\hat{\mathbf M}\mathbf G$ holds, in
# frame f and column triplet k, the block $c_{fk}\mathbf R_f$: the two rows of a rotation,
# scaled by the shape coefficient. So three columns $\mathbf G^k$ of $\mathbf G$ are right
# when, in every frame, the 2 x 3 block $\hat{\mathbf M}_f\mathbf G^k$ has two rows of
# equal length at a right angle. That is two conditions per frame on one small unknown:
# many frames pin it down. The picture: the two rows' length ratio and angle, frame by
# frame, for the SVD's own first triplet (the first three columns of the identity) and for
# the true triplet of a synthetic sequence.

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
from nrsfm.published import published_value
from nrsfm.stages.corrective import refine_triplet, search_triplet, triplet_cost
from nrsfm.stages.measurement import centre_rows, factorize, working_scale
from nrsfm.stages.relaxation import constraint_matrix, penalized_gram, triplets_from_gram
from nrsfm.stages.rotations import resolve_depth_signs, rotations_from_triplets
from nrsfm.views import figures, output_path, save_recording, show_recording, shown_path

# %%
seq = data_tools.make_synthetic(F=150, P=45, K=3, motion="smooth", seed=7)
F, P, K = seq.n_frames, seq.n_points, seq.K
M_hat = factorize(seq.W, K).M_hat  # lesson 01: the rank-3K factor, 2F x 3K
C, R = seq.extra["coefficients"], seq.rotations  # the truth: c_fk and R_f
M_true = np.concatenate([C[:, k, None, None] * R[:, :2] for k in range(K)], axis=2)
M_true = M_true.reshape(2 * F, 3 * K)
G_true = np.linalg.lstsq(M_hat, M_true, rcond=None)[0]  # M_hat G = M
print(
    f"F = {F}, P = {P}, K = {K}; max |M_hat G_true - M_true| = "
    f"{np.abs(M_hat @ G_true - M_true).max():.0e}"
)
fig, axes = plt.subplots(1, 2, figsize=(10, 3.2))
geometry = {}
for label, G in (("SVD's first triplet", np.eye(3 * K)[:, :3]), ("true G^1", G_true[:, :3])):
    r = (M_hat @ G).reshape(F, 2, 3)  # frame f: the rows r1, r2 of M_hat_f G
    n1, n2 = np.linalg.norm(r, axis=2).T
    geometry[label] = (n2 / n1, np.degrees(np.arccos((r[:, 0] * r[:, 1]).sum(1) / (n1 * n2))))
    for ax, value in zip(axes, geometry[label]):
        ax.plot(value, label=label)
axes[0].set(title="row length ratio |r2| / |r1|", xlabel="frame")
axes[1].set(title="angle between the rows (degrees)", xlabel="frame")
axes[1].legend()
plt.show()

# %% [markdown]
# The true triplet is found by least squares because the truth is known here (the maximum
# difference is at rounding level). With it, every frame's block has rows of equal length
# (ratio one) at a right angle (ninety degrees): a scaled rotation. The SVD's first triplet
# gives rows whose length ratio and angle change from frame to frame, many degrees away
# from a right angle. The rest of the lesson finds a triplet like the true one without the
# truth.
#
# ## Two linear equations per frame
#
# Write $\mathbf m_1,\mathbf m_2$ (each $1\times3K$) for the two rows of $\hat{\mathbf M}_f$.
# The rows of $\hat{\mathbf M}_f\mathbf G^k$ are $\mathbf m_1\mathbf G^k$ and
# $\mathbf m_2\mathbf G^k$; equal length and a right angle read
#
# $$\mathbf m_1\mathbf Q\mathbf m_1^\top-\mathbf m_2\mathbf Q\mathbf m_2^\top=0,\qquad
#   \mathbf m_1\mathbf Q\mathbf m_2^\top=0,\qquad \mathbf Q=\mathbf G^k\mathbf G^{k\top}.$$
#
# Both are linear in the entries of the symmetric $3K\times3K$ matrix $\mathbf Q$, so they
# are linear in its upper triangle $\mathrm{vech}(\mathbf Q)$ ($n(n+1)/2$ numbers, $n=3K$).
# The coefficient of $Q_{ij}$ ($i<j$) counts twice, since $Q_{ji}=Q_{ij}$. Stacking the
# frames gives $\mathbf A\,\mathrm{vech}(\mathbf Q)=\mathbf 0$ with $\mathbf A$ of size
# $2F\times n(n+1)/2$. We build $\mathbf A$ with numpy, compare it with the library's
# `constraint_matrix`, and test it on the true triplets' Gram matrices.

# %%
n = 3 * K
i, j = np.triu_indices(n)  # vech(Q) = Q[i, j]
twice = np.where(i == j, 1.0, 2.0)  # off-diagonal entries appear twice in m Q m'
m1, m2 = M_hat[0::2], M_hat[1::2]
A = np.empty((2 * F, i.size))
A[0::2] = twice * (m1[:, i] * m1[:, j] - m2[:, i] * m2[:, j])  # m1 Q m1' - m2 Q m2'
A[1::2] = np.where(i == j, m1[:, i] * m2[:, i], m1[:, i] * m2[:, j] + m1[:, j] * m2[:, i])
print(
    f"A is {A.shape[0]} x {A.shape[1]}; max |A - constraint_matrix| = "
    f"{np.abs(A - constraint_matrix(M_hat)).max():.0e}"
)
Q_true = [G_true[:, 3 * k : 3 * k + 3] @ G_true[:, 3 * k : 3 * k + 3].T for k in range(K)]
rel = [np.linalg.norm(A @ Q[i, j]) / (np.linalg.norm(A) * np.linalg.norm(Q)) for Q in Q_true]
print("|A vech(Q^k)| relative, k = 1..K:", np.array2string(np.array(rel), precision=0))

# %% [markdown]
# $\mathbf A$ has one row per equation (two per frame) and one column per entry of the upper
# triangle; the library's `constraint_matrix` is the same matrix. Each true Gram matrix
# $\mathbf Q^k$ satisfies all the equations to rounding level.
#
# ## The solution space
#
# There are far more equations than unknowns, yet they do not fix $\mathbf Q$: the
# singular values of $\mathbf A$ show how many directions of $\mathrm{vech}(\mathbf Q)$ it
# leaves free.

# %%
# NBVAL_CHECK_OUTPUT
_, sv_A, Vt_A = np.linalg.svd(A)
free = int(np.sum(sv_A < 1e-10 * sv_A[0]))  # (numerically) zero singular values
print(f"{sv_A.size} singular values, {free} of them zero; 2K^2 - K = {2 * K * K - K}")
last = sv_A.size - free  # the last non-zero one
print(f"the last non-zero one: sigma_{last} / sigma_1 = {sv_A[last - 1] / sv_A[0]:.1e}")
null_space = Vt_A[-free:].T  # its last right singular vectors: a basis of the solutions
figures.singular_values_figure(
    sv_A / sv_A[0], mark=last, title="singular values of A / the largest (noise-free)"
)
plt.show()

# %% [markdown]
# Fifteen singular values are zero to rounding, more than ten decades below the last
# non-zero one (the cliff in the figure): the equations leave a 15-dimensional space of
# solutions, $2K^2-K$ with K = 3. Its basis is the last 15 right singular vectors of
# $\mathbf A$.
#
# Why $2K^2-K$ (Akhter et al.)? In the true M's coordinates, $\mathbf Q'=\mathbf G^{-1}
# \mathbf Q\mathbf G^{-\top}$ is a K x K grid of 3 x 3 blocks. The equations hold for every
# frame's rotation and coefficients only if the symmetric part of each block $(k,l)$ is a
# multiple of the identity ($K(K+1)/2$ numbers), while the antisymmetric part of each block
# above the diagonal is free (three numbers each, $3K(K-1)/2$). We build that basis and
# map it back with the true $\mathbf G$:

# %%
E = np.eye(3)
anti = [np.outer(E[a], E[b]) - np.outer(E[b], E[a]) for a, b in ((0, 1), (0, 2), (1, 2))]
basis = []
for k in range(K):
    for l in range(k, K):
        for S in [E] + (anti if l > k else []):  # block (k, l) of Q'
            Qp = np.zeros((n, n))
            Qp[3 * k : 3 * k + 3, 3 * l : 3 * l + 3] = S
            Qp = Qp + Qp.T  # symmetric: block (l, k) is S'
            basis.append((G_true @ Qp @ G_true.T)[i, j])  # Q = G Q' G', as vech
basis = np.array(basis).T
n_sym, n_anti = K * (K + 1) // 2, 3 * K * (K - 1) // 2
print(f"{n_sym} symmetric + {n_anti} antisymmetric = {basis.shape[1]} basis matrices")
angle = np.degrees(subspace_angles(basis, null_space)).max()
print(f"largest angle between their span and the null space of A: {angle:.0e} degrees")

# %% [markdown]
# The six identity blocks and nine antisymmetric ones give 15 matrices, and they span the
# null space of $\mathbf A$ exactly (the angle is zero to rounding). The true Gram matrix
# $\mathbf Q^k$ is the one with a single identity block at $(k,k)$. Dai et al. show that the
# members of this space that are PSD of rank three are exactly the Gram matrices of valid
# triplets: combinations $\sum_k a_k\mathbf G^k$ of the true ones, times one rotation.
#
# ## Choosing a point: the relaxation
#
# Dai et al. pick the member of smallest nuclear norm (for a PSD matrix, its trace: small
# trace favours low rank), with a normalisation that rules out $\mathbf Q=\mathbf 0$. With
# noise, no matrix but zero satisfies the equations exactly (below, $\mathbf A$ will have
# no zero singular value), so the library's `penalized_gram` penalises the equations
# instead of imposing them:
#
# $$\min_{\mathbf Q\succeq0}\ a\,\mathrm{tr}(\mathbf Q)+\frac{\lambda}{F}\,
#   \|\mathbf A\,\mathrm{vech}(\mathbf Q)\|^2\quad\text{s.t.}\quad
#   \langle\hat{\mathbf M}^\top\hat{\mathbf M},\mathbf Q\rangle=2F,$$
#
# with $a$ a fixed scale that makes both terms dimensionless; the constraint sets the
# cameras' mean squared scale to one. We check its answer against each part of that
# problem.

# %%
Q_rel = penalized_gram(M_hat, K, lam=1e2)
eig = np.linalg.eigvalsh(Q_rel)[::-1]
print("eigenvalues of Q / the largest:", np.array2string(eig / eig[0], precision=1))
print(f"<M_hat' M_hat, Q> / 2F = {np.sum((M_hat.T @ M_hat) * Q_rel) / (2 * F):.4f}")
res = np.linalg.norm(A @ Q_rel[i, j]) / (np.linalg.norm(A) * np.linalg.norm(Q_rel))
print(f"|A vech(Q)| relative: {res:.0e}")

# %% [markdown]
# Three eigenvalues are of order one and the other six are zero to rounding: the relaxed
# $\mathbf Q$ is PSD of rank three, as a valid Gram matrix must be. The normalisation
# holds (ratio one to the printed digits), and the constraint residual is small but not
# zero: the penalty trades a little of it for a smaller trace.
#
# ## From $\mathbf Q$ to a triplet, and Dai's cost
#
# A PSD matrix of rank three is $\mathbf G\mathbf G^\top$ with
# $\mathbf G=\mathbf V_3\mathbf L_3^{1/2}$, its top three eigenvectors scaled by the
# square roots of their eigenvalues (`triplets_from_gram`). How far is it from valid? Dai's
# cost adds up, over the frames, how unequal and how far from perpendicular the rows
# $\mathbf r_1,\mathbf r_2$ of $\hat{\mathbf M}_f\mathbf G$ are:
#
# $$E(\mathbf G)=\sum_f\Big(1-\frac{\|\mathbf r_2\|^2}{\|\mathbf r_1\|^2}\Big)^2
#   +4\sum_f\Big(\frac{\mathbf r_1\cdot\mathbf r_2}{\|\mathbf r_1\|^2}\Big)^2 .$$

# %%
w, V = np.linalg.eigh(Q_rel)
G_rel = V[:, ::-1][:, :3] * np.sqrt(w[::-1][:3])  # top three eigenpairs
G_lib = triplets_from_gram(Q_rel)
gap = np.abs(G_rel @ G_rel.T - G_lib @ G_lib.T).max()
print(f"max |G G' - (G G' of triplets_from_gram)| = {gap:.0e}")


def dai_cost(G, M):
    r = (M @ G).reshape(-1, 2, 3)
    n1, n2, d = (r[:, 0] ** 2).sum(1), (r[:, 1] ** 2).sum(1), (r[:, 0] * r[:, 1]).sum(1)
    return np.sum((1 - n2 / n1) ** 2) + 4 * np.sum((d / n1) ** 2)


print(
    f"Dai's cost of the relaxed triplet: {dai_cost(G_rel, M_hat):.2e} by hand, "
    f"{triplet_cost(G_rel, M_hat):.2e} triplet_cost"
)

# %% [markdown]
# The hand-made triplet and the library's have the same Gram matrix (a triplet is fixed by
# its Gram matrix only up to a rotation on the right). Dai's cost of it is small, not zero:
# the penalty left a residual. `triplet_cost` computes the same number.
#
# ## Refinement
#
# `refine_triplet` minimises Dai's cost over $\mathbf G$ directly (Levenberg-Marquardt,
# from the relaxed triplet). To score a triplet against the truth we turn it into one
# camera per frame as lesson 03 explains (`rotations_from_triplets` lifts each block to a
# rotation, `resolve_depth_signs` fixes the sign that a negative $c_{fk}$ leaves), then
# take e_R, the mean camera error after one global alignment (`nrsfm.rotation_error`).


# %%
def triplet_e_R(G, M, R_gt):
    """e_R of the cameras of one triplet (lifted, depth signs by smoothness)."""
    cameras = resolve_depth_signs(rotations_from_triplets(M, G)[0])[0]
    return nrsfm.rotation_error(cameras, R_gt)


G_ref, cost_ref, n_iter = refine_triplet(G_rel, M_hat)
print(f"refined in {n_iter} iterations: Dai's cost {cost_ref:.0e}")
print(
    f"e_R: relaxed triplet {triplet_e_R(G_rel, M_hat, R):.3f}, "
    f"refined {triplet_e_R(G_ref, M_hat, R):.0e}"
)

# %% [markdown]
# The refinement drives Dai's cost to rounding level. The relaxed triplet's cameras were
# off by an e_R of 0.077; the refined triplet's match the truth to about eight digits.
# Which valid triplet is it? Write $\hat{\mathbf M}\mathbf G_{ref}=\mathbf M\mathbf X$
# and read the blocks $\mathbf X_k$ of $\mathbf X$ (each 3 x 3): for a valid triplet they
# are $a_k\mathbf O$, numbers $a_k$ times one common rotation $\mathbf O$.

# %%
X = np.linalg.lstsq(M_true, M_hat @ G_ref, rcond=None)[0].reshape(K, 3, 3)
a = np.sqrt((X**2).sum(axis=(1, 2)) / 3) * np.sign(np.linalg.det(X))
O = X[0] / a[0]  # the common rotation (orthogonal)
print("a_k =", np.array2string(a / np.abs(a).max(), precision=2), "(largest |a_k| = 1)")
print(
    f"max |X_k - a_k O| = {np.abs(X - a[:, None, None] * O).max():.0e}, "
    f"det O = {np.linalg.det(O):.2f}"
)

# %% [markdown]
# The refined triplet is mostly the first true triplet with its sign reversed, plus small
# parts of the other two, times one rotation (its determinant is one), up to the same
# eight digits: a valid triplet, but none of the K true ones exactly. Its coefficient
# $\sum_k a_kc_{fk}$ mixes the true coefficients too; a triplet whose mix comes near zero
# in some frames sees those frames' cameras badly (lesson 03 filters such samples).
#
# ## With noise
#
# Noise on the tracks (standard deviation 0.02 in units of W's spread, as in lesson 01)
# breaks the exact solution space: no singular value of $\mathbf A$ is zero any more.

# %%
noisy = data_tools.make_synthetic(F=150, P=45, K=3, motion="smooth", noise=0.02, seed=7)
M_n = factorize(noisy.W, K).M_hat
sv_n = np.linalg.svd(constraint_matrix(M_n), compute_uv=False)
print(
    f"noise {0.02}: sigma_30 / sigma_31 = {sv_n[29] / sv_n[30]:.2f}, "
    f"smallest sigma / sigma_1 = {sv_n[-1] / sv_n[0]:.1e}"
)
G_n, cost_n, _ = refine_triplet(triplets_from_gram(penalized_gram(M_n, K)), M_n)
e_rn = triplet_e_R(G_n, M_n, noisy.rotations)
print(f"relaxed and refined: Dai's cost {cost_n:.3f}, e_R {e_rn:.3f}")

# %% [markdown]
# With noise 0.02 the smallest singular values rise to a few thousandths of the largest and
# the cliff after the thirtieth is gone: the ratio across it is close to one (the recording
# at the end draws both spectra side by side). The relaxation and refinement still work:
# Dai's cost stays small and the cameras are off by an e_R of about 0.06.
#
# ## Several minima: the triplet search
#
# Dai's cost is not convex: a refinement ends in the minimum whose basin holds its start.
# The library's `search_triplet` therefore refines several starts in a fixed order: the
# relaxation at the penalties $\lambda=10$ and $\lambda=100$, then Gaussian random triplets
# from `numpy.random.default_rng(seed)`. It groups the results by cost (equal to a relative
# $10^{-5}$: the same minimum) and stops once the lowest cost has been reached by `hits`
# starts. Here is that loop by hand, with three hits so that random starts are needed.


# %%
def my_search(M, K, hits, seed=0, max_starts=40):
    rng, history = np.random.default_rng(seed), []
    starts = [("relaxed(lam=10)", 1e1), ("relaxed(lam=100)", 1e2)]
    while len(history) < max_starts:
        name, lam = starts.pop(0) if starts else (f"random{len(history) - 2}", None)
        if lam is None:
            G0 = rng.standard_normal((3 * K, 3))
        else:
            G0 = triplets_from_gram(penalized_gram(M, K, lam=lam, tol=1e-5))
        cost = refine_triplet(G0, M, max_iter=200, reuse=1e-3)[1]
        history.append((name, cost))
        best = min(c for _, c in history)
        if sum(abs(c - best) <= 1e-5 * best for _, c in history) >= hits:
            break
    return history


mine = my_search(M_n, K, hits=3)
lib = search_triplet(M_n, K, hits=3)
for (name, cost), (name_lib, cost_lib, _) in zip(mine, lib.history):
    print(f"{name:17s} cost {cost:.6f}   search_triplet: {name_lib:17s} {cost_lib:.6f}")

# %% [markdown]
# The hand loop and `search_triplet` refine the same starts to the same costs. Both
# relaxations reach one minimum (cost 0.029132). The first random start finds a slightly
# cheaper one (0.029099), the second a bad one more than twenty times costlier, and the
# third and fourth return to the cheapest: its third hit stops the search.
# `search_triplet` returns the distinct minima, lowest cost first. With the default of two
# hits it stops after the two relaxations, at the minimum that is only slightly costlier.
#
# ## Real motion capture (when `NRSFM_DATA` is set)
#
# On *pickup* (a person picking something up, K = 12 in the paper) the body is not exactly
# a mix of K shapes: the constraints hold only approximately. With its tracks as they are,
# the search stops after its two relaxations; we compare its e_R with the paper's for its
# method and for BMM (Dai et al.'s single triplet), from `nrsfm.published`.

# %%
MOCAP = paths.data_dir() / "mocap" if os.environ.get("NRSFM_DATA") else None
have_mocap = MOCAP is not None and (MOCAP / "pickup.mat").is_file()
if have_mocap:
    pickup = data_tools.load_mocap("pickup", data_dir=MOCAP)
    Wp, _ = centre_rows(pickup.W)
    M_p = factorize(Wp / working_scale(Wp), pickup.K).M_hat  # as the pipeline scales W
    s_p = search_triplet(M_p, pickup.K)
    e_p = triplet_e_R(s_p.G[0], M_p, pickup.rotations)
    paper = {m: published_value("mocap_rotation_error", m, "pickup") for m in ("ours", "BMM")}
    print(f"pickup: F = {pickup.n_frames}, P = {pickup.n_points}, K = {pickup.K}")
    print(
        f"search: {s_p.n_starts} starts, {len(s_p.costs)} minimum, cost {s_p.costs[0]:.4f}, "
        f"e_R {e_p:.3f}; the paper: ours {paper['ours']}, BMM {paper['BMM']}"
    )
else:
    print("no MoCap data (set NRSFM_DATA to the folder holding mocap/): this part skipped")

# %% [markdown]
# With the data, both relaxations refine to the same minimum, so the search stops after
# two starts; its single triplet's e_R is close to the paper's e_R for BMM, which also uses
# one triplet (the paper's own method averages K of them: lesson 03 and lesson 04).
#
# ## Under heavy track noise one relaxation is not enough
#
# The paper's Fig. 4 (a) adds Gaussian noise to the tracks. At a quarter of W's mean row
# standard deviation (`data_tools.add_noise(W, 0.25)`), the relaxation at $\lambda=100$
# alone refines into a bad minimum. The search's distinct minima, with the start that
# first reached each and its e_R:

# %%
if have_mocap:
    Wn, _ = centre_rows(data_tools.add_noise(pickup.W, 0.25, seed=0))
    M_pn = factorize(Wn / working_scale(Wn), pickup.K).M_hat
    s_n = search_triplet(M_pn, pickup.K, seed=0)
    e_n = np.array([triplet_e_R(G, M_pn, pickup.rotations) for G in s_n.G])
    print(f"noise 0.25: starts {', '.join(h[0] for h in s_n.history)}")
    print(f"{len(s_n.costs)} distinct minima; the best reached by {s_n.hits} starts")
    for start, cost, e, hit in zip(s_n.starts, s_n.costs, e_n, s_n.counts):
        print(f"  first reached by {start:17s} cost {cost:6.1f}  e_R {e:.2f}  ({hit} start(s))")

# %% [markdown]
# With the data: the relaxation at $\lambda=10$ lands in the cheapest minimum (cost about
# 39), whose cameras have e_R about 0.22; the relaxation at $\lambda=100$ and two random
# starts land in minima about five times costlier, and those are failures: e_R above one,
# cameras unrelated to the truth. The third random start reaches the cheapest minimum again
# and the search stops. The search returns all four minima; only the first is used.
#
# ## The recording
#
# The Rerun recording of this lesson shows the constraint spectrum as bars of
# $\log_{10}\sigma_i/\sigma_1$ (`/lesson/log10_constraint_sv/...`, noise-free and with
# noise), logged by the lesson, and a reconstruction of the noisy sequence, whose rotation
# stage starts from the search's best triplet: its camera axes per triplet, their average
# and the ground truth (`/rotations/...`), and each triplet's $|c_{fk}|$ per frame.

# %%
import rerun.blueprint as rrb

spectrum = "/lesson/log10_constraint_sv"
free_view = rrb.BarChartView(
    origin=f"{spectrum}/noise_free", name="log10 sigma_i(A) / sigma_1, noise-free: 15 zeros"
)
noisy_view = rrb.BarChartView(
    origin=f"{spectrum}/noise_0.02", name="log10 sigma_i(A) / sigma_1, noise 0.02"
)
eye = rrb.EyeControls3D(position=[1.7, -2.0, 1.4], look_target=[0, 0, 0], eye_up=[0, 0, 1])
axes_view = rrb.Spatial3DView(
    origin="/rotations", name="camera axes: triplets, average, GT", eye_controls=eye
)
coef_view = rrb.TimeSeriesView(origin="/rotation_samples/coefficient", name="|c_fk| per triplet")
layout = rrb.Blueprint(
    rrb.Horizontal(
        rrb.Vertical(free_view, noisy_view, row_shares=[3, 2]),
        rrb.Vertical(axes_view, coef_view, row_shares=[3, 2]),
        column_shares=[3, 2],
    ),
    rrb.TimePanel(state="collapsed", timeline="frame"),
    collapse_panels=True,
)

# %% [markdown]
# The spectra take the most room (the noise-free one largest), the rotations beside them.
# The spectra are not part of a reconstruction's recording: the lesson logs them in a
# function that `save_recording` calls with the open stream.


# %%
def log_spectra(rec):
    import rerun as rr

    for name, sv in (("noise_free", sv_A), ("noise_0.02", sv_n)):
        bars = rr.BarChart(np.log10(sv / sv[0] + 1e-17))
        rec.log(f"/lesson/log10_constraint_sv/{name}", bars, static=True)


result = nrsfm.reconstruct(noisy.W, K)
rrd = output_path("02_corrective_triplets.rrd")
save_recording(result, rrd, noisy, blueprint=layout, extra=log_spectra)
print(f"wrote {shown_path(rrd)} ({rrd.stat().st_size / 1e6:.2f} MB)")
show_recording(rrd)

# %% [markdown]
# ![The recording in the Rerun web viewer](../docs/notebooks/recordings/02_corrective_triplets.png)
#
# In the viewer, compare the two spectra: in the noise-free one the last 15 bars (the free
# directions) lie more than ten decades below the others; the noisy one has no cliff. Play
# the frame timeline to see the triplets' camera axes around their average and the ground
# truth.
#
# ## Summary
#
# - A valid triplet makes $\hat{\mathbf M}_f\mathbf G^k$ a scaled rotation in every frame:
#   two equations per frame, linear in $\mathbf Q^k=\mathbf G^k\mathbf G^{k\top}$
#   (`constraint_matrix`).
# - Noise-free, they leave a solution space of dimension $2K^2-K$ (the null space of
#   $\mathbf A$); its PSD rank-three members are the valid triplets' Gram matrices.
# - A convex relaxation (`penalized_gram`) picks a low-rank point, its top three eigenpairs
#   give a triplet (`triplets_from_gram`), and Levenberg-Marquardt on Dai's cost
#   (`refine_triplet`) makes it exact; the result mixes the true triplets.
# - With noise Dai's cost has several minima; `search_triplet` refines relaxations and
#   seeded random starts until the cheapest minimum is found twice.
#
# ## Exercises
#
# 1. Make the same sequence with K = 2. How many zero singular values does $\mathbf A$
#    have?
# 2. Multiply the refined triplet by a random rotation on the right,
#    $\mathbf G\mathbf O$. Does its Gram matrix change? Its Dai's cost?
# 3. Is $\mathbf G^1+\mathbf G^2$ (two true triplets added) a valid triplet? And
#    $\mathbf G^1+\mathbf G^2\mathbf O$ with a random rotation $\mathbf O$?
#
# <details><summary>Answers</summary>
#
# - To 1: six, $2K^2-K$ with K = 2.
# - To 2: neither changes: $\mathbf G\mathbf O\mathbf O^\top\mathbf G^\top=\mathbf G
#   \mathbf G^\top$, and the rows of $\hat{\mathbf M}_f\mathbf G\mathbf O$ are those of
#   $\hat{\mathbf M}_f\mathbf G$ turned by $\mathbf O$ (same lengths, same angle). A triplet
#   is fixed only up to that rotation: each triplet has its own world frame (lesson 03).
# - To 3: the sum is valid (Dai's cost zero: a mix of triplets with one common rotation);
#   with $\mathbf O$ it is not (its cost is far from zero).
#
# </details>

# %% tags=["answers"]
s2 = data_tools.make_synthetic(F=150, P=45, K=2, motion="smooth", seed=7)
sv2 = np.linalg.svd(constraint_matrix(factorize(s2.W, 2).M_hat), compute_uv=False)
assert np.sum(sv2 < 1e-10 * sv2[0]) == 6
O_r = np.linalg.qr(np.random.default_rng(1).standard_normal((3, 3)))[0]
assert np.allclose((G_ref @ O_r) @ (G_ref @ O_r).T, G_ref @ G_ref.T)
assert np.isclose(triplet_cost(G_ref @ O_r, M_hat), cost_ref, atol=1e-20)
G1, G2 = G_true[:, :3], G_true[:, 3:6]
assert triplet_cost(G1 + G2, M_hat) < 1e-20 and triplet_cost(G1 + G2 @ O_r, M_hat) > 1

# %% tags=["checks"]
# What the prose above says, checked on every run (CI).
(ratio_t, ang_t), (ratio_s, ang_s) = geometry["true G^1"], geometry["SVD's first triplet"]
assert np.abs(M_hat @ G_true - M_true).max() < 1e-9 and np.abs(ratio_t - 1).max() < 1e-9
assert np.abs(ang_t - 90).max() < 1e-6 and np.abs(ratio_s - 1).max() > 0.2
assert np.abs(ang_s - 90).max() > 10 and max(rel) < 1e-13  # "many degrees"; "rounding"
assert np.abs(A - constraint_matrix(M_hat)).max() < 1e-12 and basis.shape[1] == 15
assert free == 2 * K * K - K == 15 and sv_A[-free - 1] > 1e10 * sv_A[-free] and angle < 1e-6
assert np.all(eig[3:] / eig[0] < 1e-10) and np.all(eig[:3] / eig[0] > 0.1)
assert abs(np.sum((M_hat.T @ M_hat) * Q_rel) / (2 * F) - 1) < 5e-5 and 1e-10 < res < 1e-2
cost_rel = triplet_cost(G_rel, M_hat)
assert gap < 1e-12 and np.isclose(dai_cost(G_rel, M_hat), cost_rel) and 1e-6 < cost_rel < 0.1
assert 0.05 < triplet_e_R(G_rel, M_hat, R) < 0.1 and triplet_e_R(G_ref, M_hat, R) < 1e-7
assert np.abs(X - a[:, None, None] * O).max() < 1e-6 and np.linalg.det(O) > 0
assert abs(a[0]) == np.abs(a).max() and a[0] < 0 and np.all(np.abs(a[1:] / a[0]) < 0.1)
assert 1e-3 < sv_n[-1] / sv_n[0] < 1e-2 and sv_n[29] / sv_n[30] < 1.5
costs = [c for _, c in mine]
assert cost_n < 0.1 and 0.04 < e_rn < 0.08 and cost_ref < 1e-20
assert np.allclose(costs, [c for _, c, _ in lib.history], rtol=1e-6) and len(costs) == 6
assert costs[0] > costs[2] < costs[0] * (1 - 1e-5) and costs[3] > 20 * costs[2]
assert np.allclose(costs[4:], costs[2], rtol=1e-5) and np.isclose(costs[1], costs[0], rtol=1e-5)
if have_mocap:
    assert s_p.n_starts == 2 and len(s_p.costs) == 1 and abs(e_p - paper["BMM"]) < 0.01
    assert s_n.starts[0] == "relaxed(lam=10)" and 30 < s_n.costs[0] < 50 and e_n[0] < 0.3
    assert np.all(e_n[1:] > 1) and np.all(abs(s_n.costs[1:] / s_n.costs[0] - 5) < 1)
    assert s_n.starts[1:] == ["relaxed(lam=100)", "random0", "random1"] and s_n.n_random == 3

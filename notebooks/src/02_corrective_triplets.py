# %% [markdown]
# # 02 · Corrective triplets $\mathbf G^k$
#
# The SVD gives $\mathbf W\approx\hat{\mathbf M}\hat{\mathbf B}$ only up to an invertible
# $\mathbf G\in\mathbb R^{3K\times3K}$ (notebook 01, **Eq. 1**). Split $\mathbf G$ into $K$
# column triplets $\mathbf G^k\in\mathbb R^{3K\times3}$. By Eq. (1), the $k$-th column block of
# $\mathbf M=\hat{\mathbf M}\mathbf G$ is $[c_{fk}\mathbf R_f]_f$, so each triplet alone gives
# the cameras:
#
# $$\hat{\mathbf M}_f\mathbf G^k=c_{fk}\mathbf R_f\quad(2\times3).$$
#
# With rows $\mathbf m_1,\mathbf m_2$ of $\hat{\mathbf M}_f$ and $\mathbf Q=\mathbf G^k\mathbf G^{k\top}$
# (PSD, rank 3), orthonormal rows of $\mathbf R_f$ mean, for every frame,
#
# $$\mathbf m_1\mathbf Q\mathbf m_1^\top=\mathbf m_2\mathbf Q\mathbf m_2^\top,\qquad
#   \mathbf m_1\mathbf Q\mathbf m_2^\top=0 ,$$
#
# $2F$ equations linear in the $3K(3K+1)/2$ entries of the symmetric $\mathbf Q$. Their
# solution space has dimension $2K^2-K$ (Akhter et al.; Dai et al.'s intersection theorem,
# Fig. 1 (a)-(b) of the paper). Dai et al. pick the point of minimum nuclear norm (trace on
# the PSD cone) in it, take $\mathbf G$ from its top-3 eigenpairs and refine $\mathbf G$ by
# minimising
# $\sum_f(1-\|\mathbf r_2\|^2/\|\mathbf r_1\|^2)^2+4\sum_f(\mathbf r_1\cdot\mathbf r_2/\|\mathbf r_1\|^2)^2$.
# The paper uses **all $K$ triplets** ("organic priors in the rotation space"); how it gets
# $K$ different ones is not stated (the library's answer, the best triplet and $K-1$ refined
# from it on temporal windows, is in notebook 03).
#
# `nrsfm.stages.relaxation` and `nrsfm.stages.corrective` hold the pieces:
# `constraint_matrix` ($\mathbf A$, the $2F$ equations on $\mathrm{vech}(\mathbf Q)$);
# `penalized_gram`, a penalised PSD relaxation (trace + penalised constraint residual, mean
# squared camera scale fixed to 1) in place of Dai's minimum nuclear norm over the solution
# space; `triplets_from_gram`, the triplet of its top-3 eigenpairs; `refine_triplet`,
# Levenberg-Marquardt on Dai's cost; and `search_triplet`, the library's search: that
# relaxation at two penalties, then seeded random starts, stopped once the lowest cost has
# been reached by two starts. The cells below compare one refined relaxation with the search.

# %%
import os

for _v in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_v, "1")

import time

import matplotlib.pyplot as plt
import numpy as np
import rerun as rr

import data_tools
import nrsfm
from nrsfm.stages.corrective import refine_triplet, search_triplet, triplet_cost
from nrsfm.stages.relaxation import constraint_matrix, penalized_gram, triplets_from_gram
from nrsfm.stages.measurement import factorize
from nrsfm.metrics import camera_alignment
from nrsfm.published import published_value
from nrsfm.views import output_path, show_recording, shown_path


def relaxed_triplet(M_hat, K, lam=1e2):
    """One start: the triplet of the penalised relaxation's top-3 eigenpairs, refined on all
    frames. Returns (G, Dai's cost)."""
    G, cost, _ = refine_triplet(triplets_from_gram(penalized_gram(M_hat, K, lam=lam)), M_hat)
    return G, cost


def triplet_cameras(G, M_hat):
    """(F, 2, 3) cameras of one triplet: the nearest matrix with orthonormal rows to each
    M_f G (polar factor, keeps the frame's sign), and |c_f| (RMS row norm)."""
    B = (M_hat @ G).reshape(-1, 2, 3)
    c = np.sqrt((B**2).sum(axis=(1, 2)) / 2)
    U, _, Vt = np.linalg.svd(B, full_matrices=False)
    return U @ Vt, c


def sign_free_rotation_error(R2, R_gt, n_iter=20):
    """e_R of cameras known only up to a per-frame sign (c_fk < 0 turns R_f into -R_f).

    Alternates between the global orthogonal alignment Q (as in nrsfm.rotation_error) and
    each frame's sign, from the start that aligns the sign-free third rows r1 x r2; then
    the usual nrsfm.rotation_error of the sign-corrected cameras."""
    r3 = np.cross(R2[:, 0], R2[:, 1])
    U, _, Vt = np.linalg.svd(r3.T @ R_gt[:, 2])
    Q = U @ Vt
    s = np.ones(len(R2))
    for _ in range(n_iter):
        s_new = np.sign(np.einsum("fij,fij->f", R2 @ Q, R_gt[:, :2]))
        s_new[s_new == 0] = 1
        if np.array_equal(s_new, s) and _ > 0:
            break
        s = s_new
        Q = camera_alignment(s[:, None, None] * R2, R_gt)
    return nrsfm.rotation_error(s[:, None, None] * R2, R_gt)


# %% [markdown]
# ## Noise-free synthetic data: the constraints, the solution space, the triplets
#
# The true triplets are known here: $\mathbf G_{true}=\hat{\mathbf M}^+\mathbf M_{true}$.
# They satisfy the constraints exactly (Dai's cost $\approx0$), and the constraint matrix
# $\mathbf A$ has exactly $2K^2-K$ (near-)zero singular values: the solution space is the
# null space of $\mathbf A$, spanned by its last $2K^2-K$ right singular vectors.

# %%
seq = data_tools.default_sequence()
F, P, K = seq.n_frames, seq.n_points, seq.K
fact = factorize(seq.W / np.std(seq.W), K)
M_hat = fact.M_hat
C, R = seq.extra["coefficients"], seq.rotations
M_true = np.concatenate([C[:, k, None, None] * R[:, :2] for k in range(K)], axis=2).reshape(
    2 * F, 3 * K
)
G_true = np.linalg.lstsq(M_hat, M_true, rcond=None)[0]
true_costs = [triplet_cost(G_true[:, 3 * k : 3 * k + 3], M_hat) for k in range(K)]
print("Dai's cost of the true triplets:", np.array(true_costs))
assert max(true_costs) < 1e-15

A = constraint_matrix(M_hat)
n, d = 3 * K, 2 * K * K - K
_, sv_A, Vt = np.linalg.svd(A)  # singular values in decreasing order
basis = Vt[-d:].T  # the solution space: null space of A
print(f"A: {A.shape} (2F x n(n+1)/2 = {n * (n + 1) // 2}); null-space basis {basis.shape}")
print("smallest singular values of A:", np.array2string(sv_A[-d - 2 :], precision=2))
assert basis.shape == (n * (n + 1) // 2, d)
assert sv_A[-d] / sv_A[0] < 1e-6 and sv_A[-d - 1] / sv_A[0] > 1e-3  # a clean gap at 2K^2-K

# %% [markdown]
# The penalised relaxation's triplet, refined, and the library's search: both exact here.

# %%
t0 = time.perf_counter()
G_rel, cost_rel = relaxed_triplet(M_hat, K)
t_rel = time.perf_counter() - t0
t0 = time.perf_counter()
search = search_triplet(M_hat, K)
t_search = time.perf_counter() - t0
for label, Gs, costs, secs in (
    ("relaxed", G_rel[None], np.array([cost_rel]), t_rel),
    ("search", search.G, search.costs, t_search),
):
    e = [sign_free_rotation_error(triplet_cameras(G, M_hat)[0], R) for G in Gs]
    print(
        f"{label:8s} {len(Gs)} triplet(s) in {secs:.2f} s: "
        f"cost {np.array2string(costs, precision=1)}, "
        f"e_R {np.array2string(np.array(e), precision=1)}"
    )
    assert max(e) < 1e-5  # every triplet is exact (e_R printed above)
print(
    f"search: {search.n_starts} starts, the best minimum reached by {search.hits}, "
    f"stopped on {search.stopped!r}"
)

# %% [markdown]
# Each triplet also carries its coefficients $c_{fk}$ (the row norms of
# $\hat{\mathbf M}_f\mathbf G^k$, known up to a global sign and scale). Frames where a
# triplet's $|c_{fk}|$ is small see the camera badly: that is why the samples are later
# filtered (notebook 03). The coefficient of a refined triplet is a mixture of the true
# ones, since any linear combination of triplets of the same rotation is again one.

# %%
coeff = triplet_cameras(search.G[0], M_hat)[1]
fig, ax = plt.subplots(1, 2, figsize=(10, 3))
ax[0].plot(C)
ax[0].set_title("true coefficients c_fk", fontsize=9)
ax[1].plot(coeff / coeff.max())
ax[1].set_title("|c_f| of the search's triplet (normalised)", fontsize=9)
for a in ax:
    a.set_xlabel("frame")
plt.show()

# %% [markdown]
# ## With noise
#
# 2 % noise: the constraints no longer hold exactly; the best refined triplet of the search
# stays close.

# %%
noisy = data_tools.make_synthetic(F=150, P=45, K=3, motion="smooth", noise=0.02, seed=7)
f_noisy = factorize(noisy.W / np.std(noisy.W), K)
r_noisy = search_triplet(f_noisy.M_hat, K)
e_noisy = [
    sign_free_rotation_error(triplet_cameras(G, f_noisy.M_hat)[0], noisy.rotations)
    for G in r_noisy.G
]
print(
    "costs",
    np.array2string(r_noisy.costs, precision=3),
    " e_R",
    np.array2string(np.array(e_noisy), precision=4),
)
assert e_noisy[0] < 0.1  # the best-cost triplet comes first (e_R printed above)

# %% [markdown]
# ## MoCap (when `NRSFM_DATA` is set): the minima of Dai's cost
#
# On *pickup* ($K=12$) Dai's cost has one good minimum (its e_R is in the output below, next
# to the paper's e_R for its method and for BMM, from `nrsfm.published`). The refined
# penalised relaxation gets there; the search reaches the same minimum again from its second
# start and stops.

# %%
mocap_rows = None
if os.environ.get("NRSFM_DATA"):
    pickup = data_tools.load_mocap("pickup")
    f_p = factorize(pickup.W / np.std(pickup.W), pickup.K)
    out = {}
    t0 = time.perf_counter()
    G_p, c_p = relaxed_triplet(f_p.M_hat, pickup.K)
    out["relaxed"] = (G_p[None], np.array([c_p]), time.perf_counter() - t0)
    t0 = time.perf_counter()
    s_p = search_triplet(f_p.M_hat, pickup.K)
    out["search"] = (s_p.G, s_p.costs, time.perf_counter() - t0)
    for label, (Gs, costs, secs) in out.items():
        e_p = np.array(
            [
                sign_free_rotation_error(triplet_cameras(G, f_p.M_hat)[0], pickup.rotations)
                for G in Gs
            ]
        )
        out[label] = (costs, e_p)
        print(
            f"{label:8s} {secs:5.2f} s, {len(Gs)} distinct minima: best cost "
            f"{costs[0]:.4f}, e_R {e_p[0]:.4f}; all costs "
            f"{np.array2string(costs, precision=4, max_line_width=200)}, e_R "
            f"{np.array2string(e_p, precision=2, max_line_width=200)}"
        )
    print(
        f"search: {s_p.n_starts} starts ({', '.join(h[0] for h in s_p.history)}), the "
        f"best minimum reached by {s_p.hits}, stopped on {s_p.stopped!r}"
    )
    paper_er = {m: published_value("mocap_rotation_error", m)["pickup"] for m in ("ours", "BMM")}
    print(f"paper e_R on pickup: ours {paper_er['ours']}, BMM {paper_er['BMM']}")
    assert out["relaxed"][1][0] < 0.15 and out["search"][1][0] < 0.15
    assert np.isclose(out["relaxed"][0][0], out["search"][0][0], rtol=1e-3)
    assert s_p.hits >= 2
else:
    print("NRSFM_DATA not set: MoCap part skipped")

# %% [markdown]
# ## Under track noise: one relaxation is not enough, the search is
#
# With Gaussian noise on W of 25% of its mean row standard deviation (the top of the range of
# the paper's Fig. 4a), the penalised relaxation at one penalty ($\lambda=100$) refines into
# a bad minimum of Dai's cost. The search (`search_triplet`) tries the relaxation at two
# penalties and then seeded random starts, and stops when the lowest cost has been reached
# by two starts: it ends in a much cheaper minimum with a far smaller e_R (the cell below
# prints both, and the ratio of the costs). The seed fixes every random start. The plot
# shows cost against the sign-free e_R of every distinct minimum the search's starts
# reached (the single relaxation's among them).

# %%
if os.environ.get("NRSFM_DATA"):
    from nrsfm.stages.measurement import centre_rows, working_scale

    Wn, _ = centre_rows(data_tools.add_noise(pickup.W, 0.25, seed=0))
    f_n = factorize(Wn / working_scale(Wn), pickup.K)
    G_one, cost_one = relaxed_triplet(f_n.M_hat, pickup.K)
    srch = search_triplet(f_n.M_hat, pickup.K, seed=0)
    e_one = sign_free_rotation_error(triplet_cameras(G_one, f_n.M_hat)[0], pickup.rotations)
    e_srch = sign_free_rotation_error(triplet_cameras(srch.G[0], f_n.M_hat)[0], pickup.rotations)
    print(f"single relaxation: cost {cost_one:.1f}, e_R {e_one:.3f}")
    print(
        f"search: cost {srch.costs[0]:.1f}, e_R {e_srch:.3f}, {srch.n_starts} starts, "
        f"best reached by {srch.hits}, stopped on {srch.stopped!r}"
    )
    print(
        f"the search's minimum is {cost_one / srch.costs[0]:.1f}x cheaper than the "
        f"single relaxation's"
    )
    assert srch.costs[0] < 0.5 * cost_one and e_srch < 0.3 < e_one
    assert srch.hits >= 2
    e_minima = np.array(
        [
            sign_free_rotation_error(triplet_cameras(G, f_n.M_hat)[0], pickup.rotations)
            for G in srch.G
        ]
    )
    mocap_rows = (srch.costs, e_minima)
    print(
        f"the search's {len(srch.G)} distinct minima: costs "
        f"{np.array2string(srch.costs, precision=1)}, e_R "
        f"{np.array2string(e_minima, precision=3)}"
    )
    fig, ax = plt.subplots(figsize=(5, 3.2))
    ax.loglog(srch.costs, e_minima, "o", label="the search's minima", alpha=0.7)
    ax.loglog([cost_one], [e_one], "s", label="single relaxation", alpha=0.7)
    ax.set_xlabel("Dai's cost of the refined triplet")
    ax.set_ylabel("e_R (sign-free)")
    ax.set_title("pickup, 25% noise: minima of Dai's cost", fontsize=9)
    ax.legend(fontsize=7)
    plt.show()

# %% [markdown]
# ## Recording
#
# The cost and e_R of every minimum the search found on noisy pickup (bar charts), the
# singular values of $\mathbf A$, and per frame (timeline `frame`) the coefficient $|c_f|$
# of the search's triplet beside the true $c_{fk}$, logged here with rerun directly (the
# pipeline's recording of the full rotation stage is in notebook 03/04).

# %%
path = output_path("02_corrective_triplets.rrd")
rec = rr.RecordingStream("nrsfm-02", recording_id="02_corrective_triplets")
rec.save(path)
frames = rr.TimeColumn("frame", sequence=np.arange(F))
rec.send_columns(
    "/synthetic/coefficient/search_triplet",
    indexes=[frames],
    columns=rr.Scalars.columns(scalars=coeff),
)
for k in range(K):
    rec.send_columns(
        f"/synthetic/true_coefficient/basis_{k + 1}",
        indexes=[frames],
        columns=rr.Scalars.columns(scalars=C[:, k]),
    )
rec.log("/synthetic/constraint_singular_values", rr.BarChart(sv_A), static=True)
if mocap_rows is not None:
    rec.log("/pickup_noisy/minimum_cost", rr.BarChart(mocap_rows[0]), static=True)
    rec.log("/pickup_noisy/minimum_e_R", rr.BarChart(mocap_rows[1]), static=True)
rec.flush()
rec.disconnect()
print(f"wrote {shown_path(path)} ({path.stat().st_size / 1e3:.0f} kB)")
show_recording(path)

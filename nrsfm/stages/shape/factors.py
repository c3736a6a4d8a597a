"""Kernels of the factored shape objective of the bilinear solver.

With ``X# = B C'`` (B: F x r, C: 3P x r) and orthonormal camera rows ``R_f`` (2 x 3),

    E(B, C) = 1/2 sum_f ||W_f - R_f X_f||_F^2 + 1/2 sum_i reg_i (|B_i|^2 + |C_i|^2).   (*)

Each kernel is a few matrix products, vectorised over frames: :func:`c_step` (``argmin_C
E``), :func:`objective`, :func:`reduced_objective` (``f(B) = min_C E``, variable
projection), :func:`frame_preconditioner` (the per-frame Hessians ``d^2 E / dB_f^2``),
:func:`svd_align` and :func:`minimise` (L-BFGS on f).
"""

from __future__ import annotations

import math

import numpy as np
import scipy.linalg

__all__ = ["c_step", "minimise", "objective", "rank_certificate", "reduced_objective"]

#: L-BFGS restarts from aligned factors with a fresh preconditioner every this many
#: iterations (pickup to a relative gradient of 1e-9: 2120 iterations without, 189 with)
SEGMENT = 10


def c_step(B, Rf, W, reg):
    """argmin_C E(B, C) of (*), (3P, r), for B (F, r), orthonormal camera rows Rf (F, 2, 3),
    row-centred W (2F, P) and weights reg (r,): one 3r x 3r system shared by all points."""
    F = B.shape[0]
    Xi = np.matmul(Rf.transpose(0, 2, 1), W.reshape(F, 2, -1)).reshape(F, -1)
    return c_step_xi(B, viewing_directions(Rf), Xi, reg)


def viewing_directions(Rf):
    """``n_f = r_f1 x r_f2`` (F, 3), so that ``R_f'R_f = I - n_f n_f'``."""
    return np.cross(Rf[:, 0], Rf[:, 1])


def c_step_xi(B, n, Xi, reg):
    """:func:`c_step` from the viewing directions n (F, 3) and X_init# (F, 3P)."""
    F, r = B.shape
    P = Xi.shape[1] // 3
    D = (n[:, :, None] * B[:, None, :]).reshape(F, 3 * r)  # columns (a, i)
    N = -(D.T @ D)
    BB = B.T @ B
    for a in range(3):
        N[a * r : (a + 1) * r, a * r : (a + 1) * r] += BB
    N[np.diag_indices(3 * r)] += np.tile(reg, 3)
    rhs = (B.T @ Xi).reshape(r, 3, P).transpose(1, 0, 2).reshape(3 * r, P)
    try:
        c = scipy.linalg.cho_solve(
            scipy.linalg.cho_factor(N, check_finite=False), rhs, check_finite=False
        )
    except (np.linalg.LinAlgError, scipy.linalg.LinAlgError):
        c = np.linalg.lstsq(N, rhs, rcond=None)[0]
    return c.reshape(3, r, P).transpose(0, 2, 1).reshape(3 * P, r)


def reduced_objective(B, n, Pi, Xi, w2, reg):
    """The reduced objective ``f(B) = min_C E(B, C)`` of (*): (C, (E, data, dE/dB, 0.0)),
    dE/dC vanishing at that C. E is evaluated at C, not read from the normal equations
    (which hold only where they are solved exactly)."""
    C = c_step_xi(B, n, Xi, reg)
    E, data, gB, _ = objective(B, C, Pi, Xi, w2, reg, grad_C=False)
    return C, (E, data, gB, 0.0)


def project(Pi, Xs):
    """``Pi_f X_f`` for every frame, as (F, 3P) (``Pi_f = R_f'R_f``)."""
    F = Xs.shape[0]
    return np.matmul(Pi, Xs.reshape(F, 3, -1)).reshape(F, -1)


def objective(B, C, Pi, Xi, w2, reg, grad_C=True):
    """E(B, C) of (*), its data term and gradients (dE/dB, dE/dC; None when not
    ``grad_C``).

    With orthonormal camera rows, ``||W_f - R_f X_f||^2 = ||W_f||^2 - 2 <X_init_f, X_f> +
    <X_f, Pi_f X_f>`` (``X_init_f = R_f'W_f``, ``Pi_f = R_f'R_f``) and ``dE_data / dX# =
    Pi X - X_init``; ``w2 = ||W||_F^2``, Xi is X_init# (F, 3P). Where 3P > 9r (dense tracks)
    X# is never formed: the products go through the per-frame r x r blocks instead.
    """
    F, r = B.shape
    if Xi.shape[1] <= 9 * r:
        Xs = B @ C.T
        PX = project(Pi, Xs)
        G = PX - Xi
        data = 0.5 * max(w2 - 2.0 * float(np.vdot(Xi, Xs)) + float(np.vdot(Xs, PX)), 0.0)
        E = data + 0.5 * float(reg @ (np.sum(B**2, axis=0) + np.sum(C**2, axis=0)))
        return E, data, G @ C + B * reg, (G.T @ B + C * reg) if grad_C else None
    XiC = Xi @ C  # (F, r)
    HB = np.matmul(frame_hessians(C, Pi, np.zeros(r)), B[:, :, None])[:, :, 0]
    data = 0.5 * max(w2 - 2.0 * float(np.vdot(B, XiC)) + float(np.vdot(B, HB)), 0.0)
    E = data + 0.5 * float(reg @ (np.sum(B**2, axis=0) + np.sum(C**2, axis=0)))
    if not grad_C:
        return E, data, HB - XiC + B * reg, None
    N = _normal_matrix(B, Pi)  # (3r, 3r), rows (i, a)
    NC = (N @ C.T.reshape(3 * r, -1)).reshape(r, -1).T  # (3P, r)
    return E, data, HB - XiC + B * reg, NC - Xi.T @ B + C * reg


def _normal_matrix(B, Pi):
    """``sum_f (B_f B_f') kron Pi_f`` (3r x 3r, rows and columns (i, a))."""
    F, r = B.shape
    BB = (B[:, :, None] * B[:, None, :]).reshape(F, r * r)
    N = (BB.T @ Pi.reshape(F, 9)).reshape(r, r, 3, 3).transpose(0, 2, 1, 3)
    return N.reshape(3 * r, 3 * r)


def frame_hessians(C, Pi, reg):
    """``H_f = d^2 E / dB_f^2`` at fixed C, (F, r, r): ``H_f[i, j] = <C_i, (I_P kron Pi_f)
    C_j> + reg_i delta_ij``, from the nine (r x r) blocks ``sum_p C_i[a, p] C_j[b, p]``."""
    r = C.shape[1]
    F = Pi.shape[0]
    Ct = C.T.reshape(r, 3, -1).transpose(1, 0, 2).reshape(3 * r, -1)  # rows (a, i)
    M = (Ct @ Ct.T).reshape(3, r, 3, r).transpose(0, 2, 1, 3).reshape(9, r * r)
    H = (Pi.reshape(F, 9) @ M).reshape(F, r, r)
    H[:, np.arange(r), np.arange(r)] += reg
    return H


def _pivot_floor(H):
    """(n,) the smallest squared Cholesky pivot of each matrix of the batch H (n, r, r):
    ``1e-14`` of its mean diagonal."""
    tr = np.trace(H, axis1=1, axis2=2) / H.shape[1]
    return 1e-14 * np.maximum(tr, 1e-30 * max(float(tr.max(initial=0.0)), 1e-280))


def _cholesky(H):
    """Lower Cholesky factors of a batch of SPD matrices (n, r, r), vectorised over n; a
    pivot that rounding takes below :func:`_pivot_floor` (a singular H_f) is raised to it,
    so that the factor and its inverse stay finite."""
    r = H.shape[1]
    L = np.zeros_like(H)
    floor = _pivot_floor(H)
    for j in range(r):
        Lj = L[:, j, :j]
        d = np.sqrt(np.maximum(H[:, j, j] - np.einsum("fk,fk->f", Lj, Lj), floor))
        L[:, j, j] = d
        if j + 1 < r:
            rest = H[:, j + 1 :, j] - np.matmul(L[:, j + 1 :, :j], Lj[:, :, None])[:, :, 0]
            L[:, j + 1 :, j] = rest / d[:, None]
    return L


def _lower_inverse(L, out=None):
    """Inverses of a batch of lower-triangular matrices (n, r, r), by blocks
    (``[[A, 0], [M, D]]^-1 = [[A^-1, 0], [-D^-1 M A^-1, D^-1]]``) down to blocks of 8."""
    r = L.shape[1]
    if out is None:
        out = np.zeros_like(L)
    if r <= 8:
        out[...] = _lower_inverse_small(L)
        return out
    h = r // 2
    Ai = _lower_inverse(L[:, :h, :h], out[:, :h, :h])
    Di = _lower_inverse(L[:, h:, h:], out[:, h:, h:])
    out[:, h:, :h] = -np.matmul(Di, np.matmul(L[:, h:, :h], Ai))
    return out


def _lower_inverse_small(L):
    """:func:`_lower_inverse` by forward substitution, the batch the innermost axis."""
    n, r, _ = L.shape
    A = np.ascontiguousarray(L.transpose(1, 2, 0))  # (r, r, n)
    X = np.zeros_like(A)
    d = 1.0 / np.diagonal(L, axis1=1, axis2=2).T  # (r, n)
    for j in range(r):
        if j:
            X[j, :j] = -np.einsum("kn,kcn->cn", A[j, :j], X[:j, :j]) * d[j]
        X[j, j] = d[j]
    return np.ascontiguousarray(X.transpose(2, 0, 1))


def _factor(H):
    """Lower Cholesky factors of the SPD batch H (n, r, r): LAPACK's, or :func:`_cholesky`
    where a pivot falls below its floor or LAPACK fails."""
    try:
        L = np.linalg.cholesky(H)
    except np.linalg.LinAlgError:
        return _cholesky(H)
    if not np.all(np.diagonal(L, axis1=1, axis2=2) ** 2 >= _pivot_floor(H)[:, None]):
        return _cholesky(H)
    return L


def frame_preconditioner(C, Pi, reg):
    """(L, L^-1), each (F, r, r), with ``L_f L_f' = H_f`` (:func:`frame_hessians`; a frame
    whose H_f is singular gets ``1e-12 tr(H_f) / r`` added to its diagonal)."""
    H = frame_hessians(C, Pi, reg)
    r = H.shape[1]
    tr = np.trace(H, axis1=1, axis2=2) / r
    H[:, np.arange(r), np.arange(r)] += 1e-12 * np.maximum(tr, 1e-300)[:, None]
    L = _factor(H)
    return L, _lower_inverse(L)


def svd_align(B, C):
    """Factors of the same X# = B C' that minimise ``sum_i reg_i (|B_i|^2 + |C_i|^2)`` for
    every non-decreasing reg: ``B = U S^1/2``, ``C = V S^1/2`` with ``X# = U S V'`` (Iglesias
    et al., ECCV 2020, Sec. 3), from the QR factors of B and C."""
    Qb, _, U, s, Qc, Vt = _product_svd(B, C)
    q = np.sqrt(s)
    return (Qb @ U) * q, (Qc @ Vt.T) * q


def _product_svd(B, C):
    """``(Qb, Rb, U, s, Qc, V')``: the thin QR factors of B and C and the SVD ``U s V'``
    of ``Rb Rc'`` (``B C' = (Qb U) s (Qc V)'``)."""
    Qb, Rb = np.linalg.qr(B)
    Qc, Rc = np.linalg.qr(C)
    U, s, Vt = np.linalg.svd(Rb @ Rc.T)
    return Qb, Rb, U, s, Qc, Vt


def relative_gradient(B, C, gB, gC):
    """``||grad E|| / ||(B, C)||``."""
    g = math.sqrt(float(np.sum(gB**2) + np.sum(gC**2)))
    return g / max(math.sqrt(float(np.sum(B**2) + np.sum(C**2))), 1e-300)


def _aligned(B, C, prune_rtol):
    """:func:`svd_align` with the change of basis: (B', keep, M, M^-T) with ``B' = (B M)[:,
    :keep]`` (the last columns dropped at or below ``prune_rtol`` of the largest singular
    value of X#); M and M^-T are None where a singular value is at rounding level (no
    transport of the curvature pairs)."""
    Qb, Rb, U, s, _, _ = _product_svd(B, C)
    q = np.sqrt(s)
    keep = B.shape[1]
    if prune_rtol is not None:
        keep = max(int(np.sum(s > prune_rtol * s[0])), 1)
    B = (Qb @ U)[:, :keep] * q[:keep]
    d = np.abs(np.diagonal(Rb))
    if not (q[-1] > 1e-12 * q[0] and d.min() > 1e-12 * d.max()):
        return B, keep, None, None
    return B, keep, scipy.linalg.solve_triangular(Rb, U * q), (Rb.T @ U) / q


def rank_certificate(B, C, Pi, Xi, reg_next):
    """Whether columns more would lower E at (B, C), and along which directions: a new
    column of weight w lowers E to first order exactly when a singular value of
    ``G = dE_data / dX#`` (outside the column space of B and the row space of C') is above w.

    Returns ``(ratio, s, U)``: ``sigma_1(G) / reg_next[0]`` (at most 1 when the rank of X#
    is the prior's choice), and the m = len(reg_next) largest singular values of G with
    their left singular vectors (F, m).
    """
    G = project(Pi, B @ C.T) - Xi
    Qb, _ = np.linalg.qr(B)
    Qc, _ = np.linalg.qr(C)
    G = G - Qb @ (Qb.T @ G)
    G = G - (G @ Qc) @ Qc.T
    m = min(len(reg_next), *G.shape)
    if G.shape[0] <= G.shape[1]:
        ev, vec = np.linalg.eigh(G @ G.T)
        U = vec[:, ::-1][:, :m]
    else:
        ev, vec = np.linalg.eigh(G.T @ G)
        U = G @ vec[:, ::-1][:, :m]
        U = U / np.maximum(np.linalg.norm(U, axis=0), 1e-300)
    s = np.sqrt(np.maximum(ev[::-1][:m], 0.0))
    return float(s[0]) / max(float(reg_next[0]), 1e-300), s, U


def _half(Linv, q):
    """``L_f^-1 q_f`` for every frame: q (F, r)."""
    return np.matmul(Linv, q[:, :, None])


def _h0(Linv, q):
    """``H_f^-1 q_f = L_f^-T L_f^-1 q_f`` for every frame: q (F, r)."""
    return np.matmul(Linv.transpose(0, 2, 1), _half(Linv, q))[:, :, 0]


def _two_loop(g, S, Y, Linv):
    """``-H g`` of L-BFGS (Nocedal and Wright, Alg. 7.4) from the pairs (S, Y), oldest
    first, with the initial inverse Hessian ``gamma H_f^-1`` (:func:`_h0`; ``gamma = s'y /
    y'H_f^-1 y`` of the newest pair, 1 without pairs)."""
    q = g.copy()
    steps = []
    for s_, y_ in zip(reversed(S), reversed(Y)):
        rho = 1.0 / float(np.vdot(y_, s_))
        a = rho * float(np.vdot(s_, q))
        q -= a * y_
        steps.append((a, rho))
    gamma = 1.0
    if S:
        ly = _half(Linv, Y[-1])
        den = float(np.vdot(ly, ly))
        if den > 0:  # 0 where y underflows (factors collapsing to 0)
            gamma = float(np.vdot(S[-1], Y[-1])) / den
    d = gamma * _h0(Linv, q)
    for s_, y_, (a, rho) in zip(S, Y, reversed(steps)):
        d += (a - rho * float(np.vdot(y_, d))) * s_
    return -d


#: the line search: sufficient decrease (Armijo), the approximate Wolfe bound on the slope
#: (Hager and Zhang 2005: ``phi'(t) <= (2 ARMIJO_HZ - 1) phi'(0)``), the most backtracking
ARMIJO, ARMIJO_HZ, MAX_BACKTRACK = 1e-4, 0.1, 40
#: E is trusted to this fraction of its starting value; below, a step is judged by its slope
E_ROUNDING = 1e-12


def _line_search(reduced, B, d, E, slope, e_tol):
    """The first step ``B + t d`` from t = 1 with sufficient decrease (or, within E's
    rounding ``e_tol``, the approximate Wolfe slope), t shrunk by quadratic interpolation:
    (B_t, C_t, values), or None."""
    t = 1.0
    for _ in range(MAX_BACKTRACK):
        Bt = B + t * d
        Ct, vt = reduced(Bt)
        if vt[0] <= E + ARMIJO * t * slope:
            return Bt, Ct, vt
        if vt[0] <= E + e_tol and float(np.vdot(vt[2], d)) <= (2 * ARMIJO_HZ - 1) * slope:
            return Bt, Ct, vt
        curv = 2.0 * (vt[0] - E - slope * t)
        t_q = -slope * t * t / curv if curv > 0 else 0.5 * t
        t = min(max(t_q, 0.1 * t), 0.5 * t)
    return None


def minimise(B, problem, prune_rtol=None, segment=SEGMENT):
    """L-BFGS on the reduced objective ``f(B) = min_C E(B, C)`` of (*) from B (F, r).

    The initial inverse Hessian is the per-frame block diagonal ``H_f^-1``
    (:func:`frame_preconditioner`), refreshed every ``segment`` iterations with an
    :func:`svd_align`-ment of the factors (same X#, E never raised); the curvature pairs are
    carried through that change of basis (``s -> s M``, ``y -> y M^-T``). With
    ``prune_rtol``, aligned columns whose singular value is at most ``prune_rtol`` times the
    largest are dropped at a restart (the last ones: ``reduced`` reads the weights of the
    first ``B.shape[1]`` columns). It stops at ``gtol``, at ``max_iter``, where no descent
    is possible, or after a segment that did not lower E (its steps all within E's
    rounding): where the data term's infimum is not attained (W that the rotations do not
    explain, the organic prior's first column free) E creeps down by rounding-level steps
    while a factor grows, and more iterations would only move the answer along that valley.

    ``problem`` holds ``reduced(B)``, which returns ``(C, (E, data, dE/dB, dE/dC))`` at ``C =
    argmin_C E(B, C)`` (:func:`reduced_objective`), ``Pi`` (F, 3, 3) = ``R_f'R_f``, ``reg``
    (r,), ``gtol`` (stop at that relative gradient, :func:`relative_gradient`), ``max_iter``
    and ``record(B, C, values)``, called at the start and after every iteration.

    Returns
    -------
    B, C : the factors (aligned, r or fewer columns), rel : the final relative gradient,
    n_iter : int
    """
    reduced, record, Pi, reg = problem.reduced, problem.record, problem.Pi, problem.reg
    gtol, max_iter = problem.gtol, problem.max_iter
    C, _ = reduced(B)
    B, _, _, _ = _aligned(B, C, None)  # a start's small columns may grow
    C, vals = reduced(B)
    rel = relative_gradient(B, C, vals[2], vals[3])
    record(B, C, vals)
    n_iter, S, Y = 0, [], []
    e_tol = E_ROUNDING * abs(vals[0])
    while rel > gtol and n_iter < max_iter:
        E_start = vals[0]
        _, Linv = frame_preconditioner(C, Pi, reg[: B.shape[1]])
        failed = False  # a line search found no decrease
        for _ in range(min(segment, max_iter - n_iter)):
            with np.errstate(over="ignore", invalid="ignore"):  # pairs that underflowed:
                d = _two_loop(vals[2], S, Y, Linv)  # d not finite, memory emptied below
            slope = float(np.vdot(vals[2], d))
            if not slope < 0 and S:  # not a descent direction: memory emptied
                S, Y = [], []
                d = -_h0(Linv, vals[2])
                slope = float(np.vdot(vals[2], d))
            step = _line_search(reduced, B, d, vals[0], slope, e_tol) if slope < 0 else None
            if step is None:
                failed = True
                break
            _add_pair(S, Y, step[0] - B, step[2][2] - vals[2])
            B, C, vals = step
            n_iter += 1
            rel = relative_gradient(B, C, vals[2], vals[3])
            record(B, C, vals)
            if rel <= gtol:
                break
        r = B.shape[1]
        B, keep, M, Mt = _aligned(B, C, prune_rtol)
        C, vals = reduced(B)
        rel = relative_gradient(B, C, vals[2], vals[3])
        if (failed and not S) or vals[0] >= E_start:  # no descent possible, or a segment
            break  # that did not lower E (its steps within E's rounding): E is at its floor
        carry = not failed and keep == r and M is not None
        S, Y = ([s_ @ M for s_ in S], [y_ @ Mt for y_ in Y]) if carry else ([], [])
    return B, C, rel, n_iter


#: curvature pairs kept by L-BFGS (as many as the iterations between alignments)
MEMORY = 10


def _add_pair(S, Y, s_, y_):
    """Keep (s, y) when ``s'y > 0`` (the update stays positive definite) and y has not
    underflowed, at most MEMORY."""
    ny = float(np.linalg.norm(y_))
    if ny > 0 and float(np.vdot(s_, y_)) > 1e-12 * float(np.linalg.norm(s_)) * ny:
        S.append(s_)
        Y.append(y_)
        if len(S) > MEMORY:
            del S[0], Y[0]

"""Kernels of the factored shape objective of the bilinear solver.

With ``X# = B C'`` (B: F x r, C: 3P x r) and orthonormal camera rows ``R_f`` (2 x 3),

    E(B, C) = 1/2 sum_f ||W_f - R_f X_f||_F^2 + 1/2 sum_i reg_i (|B_i|^2 + |C_i|^2).   (*)

This module holds what every step of a solver of (*) needs, written for speed (each is a
few matrix products; no per-frame Python loop and no per-frame LAPACK call):

* :func:`c_step`: ``argmin_C E`` for fixed B, one 3r x 3r system shared by all points;
* :func:`objective`: E, its data term and both gradients;
* :func:`frame_preconditioner`: the per-frame Hessians ``H_f = d^2 E / dB_f^2`` at fixed C,
  their Cholesky factors and inverse factors (batched, vectorised over frames);
* :func:`svd_align`: the factorisation of the same X# that minimises the regulariser;
* :func:`reduced_objective`: ``f(B) = min_C E(B, C)`` (variable projection) and its gradient;
* :func:`minimise`: L-BFGS on f with the per-frame Hessians as its initial inverse
  Hessian, from aligned factors re-aligned every few iterations (its memory carried through
  the change of basis).
"""

from __future__ import annotations

import math

import numpy as np
import scipy.linalg

__all__ = ["SEGMENT", "c_step", "c_step_xi", "reduced_objective", "viewing_directions", "frame_hessians", "frame_preconditioner", "minimise", "project",
           "objective", "rank_certificate", "relative_gradient", "svd_align"]

#: L-BFGS restarts from aligned factors with a fresh preconditioner every this many
#: iterations (measured on pickup: 2120 iterations to a relative gradient of 1e-9 without
#: the alignment, 314 / 189 / 191 with it every 30 / 10 / 5)
SEGMENT = 10


def c_step(B, Rf, W, reg):
    """argmin_C E(B, C) of (*): one (3r x 3r) system shared by all points.

    For point p with unknowns ``c_p = [C_i(:, p)]_i`` (3r), the data term is
    ``sum_f ||W_f[:, p] - (B_f kron R_f) c_p||^2``: with ``A`` the (2F x 3r) matrix of rows
    ``B_f kron R_f``, the normal matrix is ``A'A + diag(reg kron 1_3)`` and the right-hand
    sides ``A'W``; :func:`c_step_xi` computes both without forming A.

    Parameters
    ----------
    B : (F, r) ndarray
    Rf : (F, 2, 3) ndarray
        Orthonormal camera rows.
    W : (2F, P) ndarray
        Row-centred measurements.
    reg : (r,) ndarray
        Non-negative regulariser weights.

    Returns
    -------
    C : (3P, r) ndarray
    """
    F = B.shape[0]
    Xi = np.matmul(Rf.transpose(0, 2, 1), W.reshape(F, 2, -1)).reshape(F, -1)
    return c_step_xi(B, viewing_directions(Rf), Xi, reg)


def viewing_directions(Rf):
    """``n_f = r_f1 x r_f2`` (F, 3), so that ``R_f'R_f = I - n_f n_f'``."""
    return np.cross(Rf[:, 0], Rf[:, 1])


def c_step_xi(B, n, Xi, reg):
    """:func:`c_step` from the viewing directions n (F, 3) and X_init# (F, 3P).

    ``A'A = sum_f (B_f'B_f) kron (I - n_f n_f') = (B'B) kron I_3 - D'D`` with D the (F x 3r)
    matrix of rows ``B_f kron n_f``, and ``A'W = B' X_init#`` (as (3r, P)): half the work of
    forming A (2F x 3r) and its products. The unknowns are ordered (coordinate, column)
    here, so that the per-frame products run over r, not over 3."""
    F, r = B.shape
    P = Xi.shape[1] // 3
    D = (n[:, :, None] * B[:, None, :]).reshape(F, 3 * r)      # columns (a, i)
    N = -(D.T @ D)
    BB = B.T @ B
    for a in range(3):
        N[a * r:(a + 1) * r, a * r:(a + 1) * r] += BB
    N[np.diag_indices(3 * r)] += np.tile(reg, 3)
    rhs = (B.T @ Xi).reshape(r, 3, P).transpose(1, 0, 2).reshape(3 * r, P)
    try:
        c = scipy.linalg.cho_solve(scipy.linalg.cho_factor(N, check_finite=False), rhs,
                                   check_finite=False)
    except (np.linalg.LinAlgError, scipy.linalg.LinAlgError):
        c = np.linalg.lstsq(N, rhs, rcond=None)[0]
    return c.reshape(3, r, P).transpose(0, 2, 1).reshape(3 * P, r)


def reduced_objective(B, n, Pi, Xi, w2, reg):
    """The reduced objective ``f(B) = min_C E(B, C)`` of (*): (C, (E, data, dE/dB, 0.0)).

    C is :func:`c_step_xi`'s, at which ``dE/dC`` vanishes (returned as 0.0): E and dE/dB
    are :func:`objective`'s without its dE/dC (a quarter of its products). E is evaluated at
    that C, not read from the normal equations (``(w2 - <A'W, c>) / 2 + ...`` holds only
    where they are solved exactly: on shark's noise-free W of rank 5 it went 1e-11 below the
    true E, and the line search followed rounding)."""
    C = c_step_xi(B, n, Xi, reg)
    E, data, gB, _ = objective(B, C, Pi, Xi, w2, reg, grad_C=False)
    return C, (E, data, gB, 0.0)


def project(Pi, Xs):
    """``Pi_f X_f`` for every frame, as (F, 3P) (``Pi_f = R_f'R_f``)."""
    F = Xs.shape[0]
    return np.matmul(Pi, Xs.reshape(F, 3, -1)).reshape(F, -1)


def objective(B, C, Pi, Xi, w2, reg, grad_C=True):
    """E(B, C) of (*), its data term and gradients (dE/dB, dE/dC; dE/dC None when not
    ``grad_C``).

    With orthonormal camera rows, ``||W_f - R_f X_f||^2 = ||W_f||^2 - 2 <X_init_f, X_f> +
    <X_f, Pi_f X_f>`` (``X_init_f = R_f'W_f``, ``Pi_f = R_f'R_f``), and
    ``dE_data / dX# = G = Pi X - X_init``. ``w2 = ||W||_F^2``; Xi is X_init# (F, 3P).

    Where 3P > 9r (many points: dense tracks) everything is computed in factored form,
    without forming X# (F x 3P): ``G C = H_f B_f - X_init# C`` with ``H_f`` the per-frame
    blocks of :func:`frame_hessians` (no weight), ``G'B = N C - X_init#' B`` with N the
    normal matrix of :func:`c_step` (no weight), and the data term from the same products:
    two passes over X_init# per call instead of six over F x 3P arrays (30,000 points x 100
    frames: 0.11 s -> 0.03 s); with few points (MoCap) the per-frame r x r blocks cost more
    than X# itself, and X# is formed.
    """
    F, r = B.shape
    if Xi.shape[1] <= 9 * r:
        Xs = B @ C.T
        PX = project(Pi, Xs)
        G = PX - Xi
        data = 0.5 * max(w2 - 2.0 * float(np.vdot(Xi, Xs)) + float(np.vdot(Xs, PX)), 0.0)
        E = data + 0.5 * float(reg @ (np.sum(B ** 2, axis=0) + np.sum(C ** 2, axis=0)))
        return E, data, G @ C + B * reg, (G.T @ B + C * reg) if grad_C else None
    XiC = Xi @ C                                               # (F, r)
    HB = np.matmul(frame_hessians(C, Pi, np.zeros(r)), B[:, :, None])[:, :, 0]
    data = 0.5 * max(w2 - 2.0 * float(np.vdot(B, XiC)) + float(np.vdot(B, HB)), 0.0)
    E = data + 0.5 * float(reg @ (np.sum(B ** 2, axis=0) + np.sum(C ** 2, axis=0)))
    if not grad_C:
        return E, data, HB - XiC + B * reg, None
    N = _normal_matrix(B, Pi)                                  # (3r, 3r), rows (i, a)
    NC = (N @ C.T.reshape(3 * r, -1)).reshape(r, -1).T          # (3P, r)
    return E, data, HB - XiC + B * reg, NC - Xi.T @ B + C * reg


def _normal_matrix(B, Pi):
    """``sum_f (B_f B_f') kron Pi_f`` (3r x 3r, rows and columns (i, a))."""
    F, r = B.shape
    BB = (B[:, :, None] * B[:, None, :]).reshape(F, r * r)
    return (BB.T @ Pi.reshape(F, 9)).reshape(r, r, 3, 3).transpose(0, 2, 1, 3).reshape(3 * r, 3 * r)


def frame_hessians(C, Pi, reg):
    """``H_f = d^2 E / dB_f^2`` at fixed C, (F, r, r): ``H_f[i, j] = <C_i, (I_P kron Pi_f)
    C_j> + reg_i delta_ij``, from the nine (r x r) blocks ``sum_p C_i[a, p] C_j[b, p]``."""
    r = C.shape[1]
    F = Pi.shape[0]
    Ct = C.T.reshape(r, 3, -1).transpose(1, 0, 2).reshape(3 * r, -1)     # rows (a, i)
    M = (Ct @ Ct.T).reshape(3, r, 3, r).transpose(0, 2, 1, 3).reshape(9, r * r)
    H = (Pi.reshape(F, 9) @ M).reshape(F, r, r)
    H[:, np.arange(r), np.arange(r)] += reg
    return H


def _pivot_floor(H):
    """(n,) the smallest squared Cholesky pivot of each matrix of the batch H (n, r, r):
    ``1e-14`` of its mean diagonal (see :func:`_cholesky`)."""
    tr = np.trace(H, axis1=1, axis2=2) / H.shape[1]
    return 1e-14 * np.maximum(tr, 1e-30 * max(float(tr.max(initial=0.0)), 1e-280))


def _cholesky(H):
    """Lower Cholesky factors of a batch of SPD matrices (n, r, r), vectorised over n.

    A pivot that rounding takes below ``1e-14`` of its matrix's mean diagonal (a singular
    H_f: shark's exact W on random cameras) is raised to that floor, so that the factor and
    its inverse stay finite (before, the pivot went to 1e-300 and the inverse overflowed)."""
    r = H.shape[1]
    L = np.zeros_like(H)
    floor = _pivot_floor(H)
    for j in range(r):
        Lj = L[:, j, :j]
        d = np.sqrt(np.maximum(H[:, j, j] - np.einsum("fk,fk->f", Lj, Lj), floor))
        L[:, j, j] = d
        if j + 1 < r:
            L[:, j + 1:, j] = (H[:, j + 1:, j]
                               - np.matmul(L[:, j + 1:, :j], Lj[:, :, None])[:, :, 0]) / d[:, None]
    return L


def _lower_inverse(L, out=None):
    """Inverses of a batch of lower-triangular matrices (n, r, r): by blocks
    (``[[A, 0], [M, D]]^-1 = [[A^-1, 0], [-D^-1 M A^-1, D^-1]]``, batched products, written
    into one array) down to blocks of at most 8, which :func:`_lower_inverse_small` inverts
    (drink, 1102 matrices of 21 x 21: 3 - 5 ms, against 5 - 6 ms by forward substitution
    alone)."""
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
    """:func:`_lower_inverse` by forward substitution with the batch as the innermost axis
    (every step a contiguous multiply-add over n)."""
    n, r, _ = L.shape
    A = np.ascontiguousarray(L.transpose(1, 2, 0))                  # (r, r, n)
    X = np.zeros_like(A)
    d = 1.0 / np.diagonal(L, axis1=1, axis2=2).T                    # (r, n)
    for j in range(r):
        if j:
            X[j, :j] = -np.einsum("kn,kcn->cn", A[j, :j], X[:j, :j]) * d[j]
        X[j, j] = d[j]
    return np.ascontiguousarray(X.transpose(2, 0, 1))


def _factor(H):
    """Lower Cholesky factors of the SPD batch H (n, r, r): LAPACK's, batched by numpy, or
    :func:`_cholesky` (with its pivot floor) where a pivot of LAPACK's falls below that
    floor or LAPACK fails."""
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
    every non-decreasing reg: ``B = U S^1/2``, ``C = V S^1/2`` with ``X# = U S V'`` (Iglesias,
    Olsson, Oernhag, ECCV 2020, Sec. 3), computed from the QR factors of B and C (an
    r x r SVD). Never raises E; the largest singular value goes to the smallest weight."""
    Qb, _, U, s, Qc, Vt = _product_svd(B, C)
    q = np.sqrt(s)
    return (Qb @ U) * q, (Qc @ Vt.T) * q


def _product_svd(B, C):
    """``(Qb, Rb, U, s, Qc, V')``: the thin QR factors of B and C and the SVD ``U s V'``
    of ``Rb Rc'`` (so that ``B C' = (Qb U) s (Qc V)'``), shared by :func:`svd_align` and
    :func:`_aligned`."""
    Qb, Rb = np.linalg.qr(B)
    Qc, Rc = np.linalg.qr(C)
    U, s, Vt = np.linalg.svd(Rb @ Rc.T)
    return Qb, Rb, U, s, Qc, Vt


def relative_gradient(B, C, gB, gC):
    """``||grad E|| / ||(B, C)||`` (scale-free)."""
    g = math.sqrt(float(np.sum(gB ** 2) + np.sum(gC ** 2)))
    return g / max(math.sqrt(float(np.sum(B ** 2) + np.sum(C ** 2))), 1e-300)


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
    """Whether columns more would lower E at (B, C), and along which directions.

    ``G = dE_data / dX#`` with its components in the column space of B and the row space
    of C' removed; a new column of weight w lowers E to first order exactly when it pairs
    with a singular value of that G above w. Singular pairs from the Gram matrix of the
    shorter side.

    Parameters
    ----------
    B, C : (F, r), (3P, r) ndarray
    Pi, Xi : (F, 3, 3), (F, 3P) ndarray
        ``R_f'R_f`` and X_init#.
    reg_next : (m,) ndarray
        The weights of the next m columns (non-decreasing).

    Returns
    -------
    ratio : float
        ``sigma_1(G_perp) / reg_next[0]``: at most 1 when the rank of ``X# = B C'`` is the
        prior's choice and not a cap.
    s, U : (m,), (F, m) ndarray
        The m largest singular values of G_perp and their left singular vectors.
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
        if den > 0:                     # 0 where y underflows (factors collapsing to 0)
            gamma = float(np.vdot(S[-1], Y[-1])) / den
    d = gamma * _h0(Linv, q)
    for s_, y_, (a, rho) in zip(S, Y, reversed(steps)):
        d += (a - rho * float(np.vdot(y_, d))) * s_
    return -d


#: the line search: sufficient decrease (Armijo), the approximate Wolfe test's bound on the
#: slope at the step (Hager and Zhang 2005: ``phi'(t) <= (2 ARMIJO_HZ - 1) phi'(0)``), and
#: the most backtracking steps
ARMIJO, ARMIJO_HZ, MAX_BACKTRACK = 1e-4, 0.1, 40
#: E is trusted to this fraction of its value at the start of :func:`minimise`: below it,
#: a step is judged by its slope (E is a difference of terms of the size of ||W||^2)
E_ROUNDING = 1e-12


def _line_search(reduced, B, d, E, slope, e_tol):
    """The first step ``B + t d`` from t = 1 with sufficient decrease, or, where the change
    of E is within its rounding ``e_tol``, with the approximate Wolfe slope (t shrunk by
    quadratic interpolation, kept in [0.1 t, 0.5 t]): (B_t, C_t, values), or None."""
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


def minimise(B, reduced, Pi, reg, gtol, max_iter, on_iterate=None, segment=None,
             prune_rtol=None):
    """L-BFGS on the reduced objective ``f(B) = min_C E(B, C)`` of (*) from B (F, r).

    The initial inverse Hessian of L-BFGS is the per-frame block diagonal ``H_f^-1``
    (``H_f = d^2 E / dB_f^2`` at the current C, :func:`frame_preconditioner`), refreshed
    every ``segment`` iterations together with an :func:`svd_align`-ment of the factors
    (which keeps X# and never raises E; without it the columns sort their singular values
    among the weights over hundreds of iterations). The curvature pairs are carried
    through the alignment's change of basis (``s -> s M``, ``y -> y M^-T``), so the
    restarts do not empty L-BFGS's memory; the line search asks for sufficient decrease
    from the full step (:func:`_line_search`). With ``prune_rtol``, aligned columns whose
    singular value is at most ``prune_rtol`` times the largest are dropped at a restart
    (they are the last ones, so the weights of the others do not change; ``reduced`` must
    read the weights of the first ``B.shape[1]`` columns; the memory is emptied then);
    whether they should stay zero is the caller's test (:func:`rank_certificate`).

    Parameters
    ----------
    B : (F, r) ndarray
    reduced : callable(B) -> (C, (E, data, gB, gC))
        ``C = argmin_C E(B, C)`` and, at (B, C), the objective, its data term (or any
        other measure) and its gradients (gC may be 0.0: it vanishes at that C), as
        :func:`reduced_objective` returns them.
    Pi : (F, 3, 3) ndarray
        ``R_f'R_f``.
    reg : (r,) ndarray
    gtol : float
        Stop at a relative gradient norm (:func:`relative_gradient`) at most gtol.
    max_iter : int
    on_iterate : callable(B, C, values) or None
        Called at the start and after every iteration (e.g. to record a history).
    segment : int, optional
        Iterations between restarts (default :data:`SEGMENT`).
    prune_rtol : float, optional
        Drop the columns that die (above).

    Returns
    -------
    B, C : the factors (aligned, r or fewer columns), rel : the final relative gradient,
    n_iter : int
    """
    segment = SEGMENT if segment is None else segment
    C, _ = reduced(B)
    B, _, _, _ = _aligned(B, C, None)               # a start's small columns may grow
    C, vals = reduced(B)
    rel = relative_gradient(B, C, vals[2], vals[3])
    if on_iterate is not None:
        on_iterate(B, C, vals)
    n_iter, S, Y = 0, [], []
    e_tol = E_ROUNDING * abs(vals[0])
    while rel > gtol and n_iter < max_iter:
        _, Linv = frame_preconditioner(C, Pi, reg[:B.shape[1]])
        failed = False                              # a line search found no decrease
        for _ in range(min(segment, max_iter - n_iter)):
            d = _two_loop(vals[2], S, Y, Linv)
            slope = float(np.vdot(vals[2], d))
            if not slope < 0 and S:                 # not a descent direction: memory emptied
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
            if on_iterate is not None:
                on_iterate(B, C, vals)
            if rel <= gtol:
                break
        r = B.shape[1]
        B, keep, M, Mt = _aligned(B, C, prune_rtol)
        C, vals = reduced(B)
        rel = relative_gradient(B, C, vals[2], vals[3])
        if failed and not S:                        # no descent possible (rounding)
            break
        carry = not failed and keep == r and M is not None
        S, Y = ([s_ @ M for s_ in S], [y_ @ Mt for y_ in Y]) if carry else ([], [])
    return B, C, rel, n_iter


#: curvature pairs kept by L-BFGS (as many as the iterations between alignments: with the
#: pipeline's rotations, 5 / 10 / 20 / 40 pairs take drink 0.70 / 0.76 / 0.83 / 0.93 s,
#: pickup 0.21 / 0.22 / 0.23 / 0.25 s, shark 162 / 112 / 121 / 192 iterations;
#: measured)
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

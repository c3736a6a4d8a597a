"""Perspective refinement: pinhole cameras with translation and the low-rank shape under the
organic prior, started from the orthographic answer.

The paper's camera is orthographic (Conclusion: it may fail under strong perspective). With
the camera's intrinsics, the image tracks become normalised coordinates ``x = K_cam^-1 [u v 1]'``
and this stage fits the pinhole model

    x_fp = pi(R_f S_fp + (a_f, b_f, 1)),      pi(Y) = (Y_1 / Y_3, Y_2 / Y_3),
    S_f = sum_k C_fk B_k   (3 x P, centred: sum_p B_k[:, p] = 0),

by minimising

    E = 1/2 sum_fp m_fp |pi(...) - x_fp|^2 + 1/2 sum_k reg_k (|C_k|^2 + |B_k|^2),      (*)

``m_fp`` the observed mask, ``reg_k = mu a_k`` the orthographic shape stage's weights (the
organic prior of Eq. 10 in the factored form of the bilinear solver, ``a_1 = 0``).

``S_f`` is the camera-frame shape divided by the depth of its centroid: ``(R_f X_f + t_f) /
t_f,z = R_f S_f + (a_f, b_f, 1)``. Dividing each frame by a number keeps ``X#`` at rank K, so
(*) is the low-rank perspective model with its scale ambiguity removed, and the orthographic
answer on ``x`` (shapes in the same units at weak perspective) is its start. What the
orthographic model cannot tell is each frame's depth order, ``(R_f, S_f)`` or
``(Rz(pi) R_f, -S_f)`` (the same orthographic image, depths reversed): the rank-K
orthographic answer is started in three orders (as it has them, all reversed, each frame's
with the lower perspective residual), each held through a first fit, after which each
frame's order is asked again after every step. From every start (*) is fitted without the
prior; a fit that comes within ``MERGE_TOL`` of an earlier one's answer stops (the same
minimum). Where the starts reach more than one minimum, one more start is the
*continuation*: the rank-1 perspective fit, then K - 1 more columns started small (where
all three reach one minimum, it has ended there too in every synthetic row of the
benchmark). The best of these fits gives the noise and with it the prior's balance; the fit
with the prior starts from each distinct minimum without it, and the answer is the lowest E
of those within ``MAX_DEPTH_RATIO`` (:func:`refine_perspective`; why:
``docs/studies/perspective.md``). Fits stop at ``LOOSE_TOL`` while the depth orders settle;
the best ones (within ``POLISH_MARGIN`` of the lowest E) go on to the settings' ``tol``. A
fit whose depth ratio rises above ``MAX_DEPTH_RATIO`` stops there (it cannot be the
answer); only where no fit stays within it are they taken on without that bound.

Minimised by Levenberg-Marquardt with the analytic Jacobian; the larger of the per-frame
block set (rotation, translation, coefficients) and the per-point one (the basis) is
eliminated (Schur complement, as in bundle adjustment), the basis kept centred by a
multiplier, its factors rebalanced to the prior's minimum after each step. A large reduced
system in the basis is solved by conjugate gradients (each point's block as preconditioner,
to ``CG_TOL`` of the residual, less near an exact fit), and factorised where they do not
converge within ``CG_MAX_ITER``.

References: Xiao and Kanade (2005), Del Bue et al. (2006), Hartley and Vidal (2008) on
perspective NRSfM; Triggs et al. (2000) on the Schur complement in bundle adjustment.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from scipy.linalg import cho_factor, cho_solve

from ..validation import check_integer, check_positive

__all__ = [
    "PerspectiveResult",
    "PerspectiveSettings",
    "check_intrinsics",
    "normalise",
    "refine_perspective",
]

_RZ = np.diag([-1.0, -1.0, 1.0])  # Rz(pi): the orthographic image's depth reversal
_SMALL = 1e-3  # the continuation's new columns, relative to the first column's size
#: entries of the per-frame blocks N_f' N_f held at once while the Schur complement is built
SCHUR_CHUNK = 4_000_000
#: rounds of depth orders re-chosen at the answer and the fit repeated, at most
MAX_FLIP_ROUNDS = 3
#: relative decrease of E at which fits stop while the depth orders settle and before
#: they are compared (the best are taken on to the settings' tol)
LOOSE_TOL = 1e-3
#: basis unknowns (3 K P) from which the reduced system is solved by conjugate gradients
#: (a Newton step to ``CG_TOL`` of its residual) rather than factorised: 200 x 100, K = 2,
#: 9 ms against 26 ms a step; K = 1 (300 unknowns): 7 against 5 ms
CG_UNKNOWNS = 400
#: relative distance of the camera points at which a fit is taken to be reaching the
#: minimum of an earlier one (and stopped)
MERGE_TOL = 1e-2
#: fits taken on to the settings' tol: those whose E at LOOSE_TOL is within this
#: fraction of the lowest (taking a fit on lowered its E by at most 2.9 % on the real sets
#: at K = 1-3 and the synthetic F = 100 sequences of the benchmark, except one far fit)
POLISH_MARGIN = 0.1
#: the largest damping (Marquardt's lam) of a step whose small decrease counts as converged
MAX_CONVERGED_DAMPING = 1.0
#: Marquardt's scaling of the coefficients and the basis at least this fraction of its mean
#: (the continuation's small new columns: their own scale let steps run off)
DAMPING_FLOOR = 1e-2
#: E below this fraction of the tracks' spread (1/2 sum of squares about each frame's
#: centroid) is rounding (an exact fit): converged
ROUNDING_E = 1e-28
#: the conjugate gradients' residual at a step, relative to the first (an inexact Newton
#: step); at most CG_MAX_ITER of them, then the factorisation for the rest of the fit
CG_TOL = 1e-2
CG_MAX_ITER = 50
#: the largest ratio of two points' depths in one frame for an answer to count as a camera
#: outside the object: (d + r) / (d - r) = 10 puts the camera d = 11/9 r from the centroid
#: of an object of radius r; a fit beyond it stretches points towards the camera's centre
#: and away (the depth the data leave undetermined), and loses to any answer within it; a
#: fit that rises above it stops there
MAX_DEPTH_RATIO = 10.0


@dataclass(frozen=True)
class PerspectiveSettings:
    """Settings of the perspective refinement.

    Parameters
    ----------
    max_iter : int
        Levenberg-Marquardt iterations of one fit (a start in one set of depth orders), at
        most.
    tol : float
        Stop when a step close to Gauss-Newton's (damping at most
        ``MAX_CONVERGED_DAMPING``) lowers E by less than ``tol E``, when no step can lower
        it by as much, or at rounding level (``ROUNDING_E``).

    Raises
    ------
    ValueError
        ``max_iter`` below 1, ``tol`` not positive.
    """

    max_iter: int = 200
    tol: float = 1e-6

    def __post_init__(self):
        check_integer(self.max_iter, "max_iter", minimum=1)
        check_positive("tol", self.tol)


@dataclass
class PerspectiveResult:
    """The perspective refinement (:func:`refine_perspective`).

    Attributes
    ----------
    rotations : (F, 3, 3) ndarray
    translations : (F, 3) ndarray
        ``(a_f, b_f, 1)``: the world origin (the shape's centroid) in each camera, in units
        of its depth.
    shapes : (F, 3, P) ndarray
        ``S_f`` in the world frame, in units of the centroid's depth in frame f.
    intrinsics : (3, 3) ndarray
    start : {"direct", "direct 2", "direct 3", "continuation"}
        The start whose E was lowest (among the answers within ``MAX_DEPTH_RATIO``): the
        rank-K orthographic answer in the depth orders it has, all reversed, or each frame's
        own (:func:`_orders`); or the rank-1 perspective fit with K - 1 small columns added.
    objectives : dict
        Final E of each start run.
    noise : float
        RMS noise of x per degree of freedom of the fit without prior (units of x).
    mu : float
        The prior's balance from ``noise``; ``reg = mu a`` the weights of (*).
    reg : (K,) ndarray
    history : dict of ndarrays
        Per iteration of the answer's path, its fit without prior (in its last depth orders)
        then with the prior: ``cost`` (E of the fit's objective), ``data_term``,
        ``damping``, ``prior`` (0, then 1 from the first iteration with the prior).
    n_iter : int
    converged : bool
        The chosen fit stopped by ``tol`` (:class:`PerspectiveSettings`), not ``max_iter``.
    tol : float
        The settings' ``tol``.
    depth_ratio : float
        The largest ratio of two points' depths in one frame: above ``MAX_DEPTH_RATIO`` the
        fit put points near the camera's centre (no start stayed within it).
    reprojection_before, reprojection_after : float
        RMS image distance in pixels (of the observed points): the orthographic answer's
        orthographic projection, and the refined perspective projection.
    """

    rotations: np.ndarray
    translations: np.ndarray
    shapes: np.ndarray
    intrinsics: np.ndarray
    start: str
    objectives: dict
    noise: float
    mu: float
    reg: np.ndarray
    history: dict = field(default_factory=dict)
    n_iter: int = 0
    converged: bool = False
    depth_ratio: float = float("nan")
    tol: float = float("nan")
    reprojection_before: float = float("nan")
    reprojection_after: float = float("nan")

    @property
    def camera_points(self):
        """(F, 3, P): the points in each camera, ``R_f S_f + t_f`` (depth units)."""
        return self.rotations @ self.shapes + self.translations[:, :, None]


def check_intrinsics(intrinsics):
    """The (3, 3) camera matrix of ``intrinsics``.

    Parameters
    ----------
    intrinsics : (3, 3) array_like or sequence of 3 or 4 numbers
        A camera matrix ``[[fx, s, cx], [0, fy, cy], [0, 0, 1]]``, or ``(f, cx, cy)``, or
        ``(fx, fy, cx, cy)`` (pixels).

    Returns
    -------
    (3, 3) ndarray

    Raises
    ------
    ValueError
        Another shape, a non-finite entry, a focal length not positive, a last row other
        than ``(0, 0, 1)`` or a non-zero entry below the diagonal.

    Examples
    --------
    >>> check_intrinsics((800, 320, 240))[0]
    array([800.,   0., 320.])
    """
    try:
        A = np.array(intrinsics, dtype=float)
    except (TypeError, ValueError):
        raise ValueError(
            f"intrinsics must be a 3 x 3 camera matrix or (f, cx, cy) or (fx, fy, cx, cy); "
            f"got {intrinsics!r}"
        ) from None
    if A.shape in ((3,), (4,)):
        fx, fy, cx, cy = (A[0], A[0], A[1], A[2]) if A.size == 3 else A
        A = np.array([[fx, 0.0, cx], [0.0, fy, cy], [0.0, 0.0, 1.0]])
    if A.shape != (3, 3):
        raise ValueError(
            f"intrinsics must be a 3 x 3 camera matrix or (f, cx, cy) or (fx, fy, cx, cy); "
            f"got shape {A.shape}"
        )
    if not np.all(np.isfinite(A)):
        raise ValueError("intrinsics must be finite")
    if not (A[0, 0] > 0 and A[1, 1] > 0):
        raise ValueError(f"intrinsics: focal lengths must be positive; got {A[0, 0]}, {A[1, 1]}")
    if not (np.array_equal(A[2], [0.0, 0.0, 1.0]) and A[1, 0] == 0):
        raise ValueError(
            f"intrinsics: a camera matrix is upper triangular with last row "
            f"(0, 0, 1); got {A.tolist()}"
        )
    return A


def normalise(W, intrinsics):
    """Normalised image coordinates (F, 2, P) of pixel tracks W (2F, P): ``K_cam^-1 [u v 1]'``.

    NaN (a point not seen) stays NaN.
    """
    A = check_intrinsics(intrinsics)
    u = np.asarray(W, float).reshape(-1, 2, np.shape(W)[-1])
    y = (u[:, 1] - A[1, 2]) / A[1, 1]
    x = (u[:, 0] - A[0, 2] - A[0, 1] * y) / A[0, 0]
    return np.stack([x, y], axis=1)


def _pixels(xn, A):
    """Pixels (F, 2, P) of normalised coordinates (F, 2, P)."""
    return np.stack(
        [A[0, 0] * xn[:, 0] + A[0, 1] * xn[:, 1] + A[0, 2], A[1, 1] * xn[:, 1] + A[1, 2]], axis=1
    )


def _skew(v):
    """(..., 3, 3) cross-product matrices of (..., 3) vectors."""
    O = np.zeros(v.shape[:-1] + (3, 3))
    O[..., 0, 1], O[..., 0, 2], O[..., 1, 2] = -v[..., 2], v[..., 1], -v[..., 0]
    return O - np.swapaxes(O, -1, -2)


def _rodrigues(w):
    """(F, 3, 3) rotations exp([w]x) of (F, 3) rotation vectors."""
    th = np.linalg.norm(w, axis=1)[:, None, None]
    Kx = _skew(w)
    small = th < 1e-8
    a = np.where(small, 1.0, np.sin(th) / np.where(small, 1.0, th))
    b = np.where(small, 0.5, (1 - np.cos(th)) / np.where(small, 1.0, th) ** 2)
    return np.eye(3) + a * Kx + b * (Kx @ Kx)


class _Fit:
    """(*) for one set of data: the residual, E and the Levenberg-Marquardt steps."""

    def __init__(self, x, mask, reg):
        self.x, self.m, self.reg = x, mask, np.asarray(reg, float)
        self.factorise = False  # the reduced system by Cholesky (conjugate gradients failed)
        n = np.maximum(mask.sum(1), 1)[:, None, None]
        centroid = (x * mask[:, None]).sum(2, keepdims=True) / n
        self.spread = 0.5 * float(np.sum(mask[:, None] * (x - centroid) ** 2))

    def residual(self, R, ab, C, B):
        S = (C @ B.reshape(B.shape[0], -1)).reshape(C.shape[0], 3, -1)
        Y = R @ S
        Y[:, :2] += ab[:, :, None]
        Y[:, 2] += 1.0
        return Y, S, self.m[:, None] * (Y[:, :2] / Y[:, 2:3] - self.x)

    def cost(self, R, ab, C, B):
        Y, _, r = self.residual(R, ab, C, B)
        if not np.all(Y[:, 2][self.m > 0] > 0):
            return np.inf, np.inf  # a point behind its camera
        data = 0.5 * float(np.sum(r**2))
        prior = 0.5 * float(np.sum(self.reg * (np.sum(C**2, 0) + np.sum(B**2, axis=(1, 2)))))
        return data + prior, data

    def normal_equations(self, R, ab, C, B):
        """Gradient and Gauss-Newton blocks of (*): frames (F, nf), points (P, 3K), and the
        cross blocks in their Kronecker form: the basis entry (k, c) of point p enters
        frame f as C_fk times ``M[f, :, p, c]`` (M: (F, nf, P, 3))."""
        Y, S, r = self.residual(R, ab, C, B)
        F, K, P = C.shape[0], C.shape[1], B.shape[2]
        nf = 5 + K
        iz = self.m / Y[:, 2]  # d pi_i / d Y = iz (e_i - u_i e_3), masked; u = pi(Y)
        u = Y[:, :2] / Y[:, 2:3]  # (F, 2, P)
        q = Y - np.array([0.0, 0.0, 1.0])[None, :, None]  # R_f S_f (F, 3, P)
        q[:, :2] -= ab[:, :, None]
        # d pi_i / d(w, a, b, C_f) (F, 2, nf, P); d(R S) = w x (R S), so d pi_i / dw =
        # (R S) x (d pi_i / d Y): the cross products written out
        Jf = np.zeros((F, 2, nf, P))
        izu = iz[:, None] * u
        Jf[:, 0, 0], Jf[:, 0, 2] = -izu[:, 0] * q[:, 1], -iz * q[:, 1]
        Jf[:, 0, 1] = iz * q[:, 2] + izu[:, 0] * q[:, 0]
        Jf[:, 1, 0] = -izu[:, 1] * q[:, 1] - iz * q[:, 2]
        Jf[:, 1, 1], Jf[:, 1, 2] = izu[:, 1] * q[:, 0], iz * q[:, 0]
        Jf[:, 0, 3], Jf[:, 1, 4] = iz, iz
        RB = (R @ B.transpose(1, 0, 2).reshape(3, K * P)).reshape(F, 3, K, P)  # R_f B_k
        Jf[:, :, 5:] = iz[:, None, None] * RB[:, :2] - izu[:, :, None] * RB[:, 2:3]
        # d pi_i / d B_k[:, p] per unit of C_fk: (F, 2, 3, P)
        JR = iz[:, None, None] * R[:, :2, :, None] - izu[:, :, None] * R[:, 2, None, :, None]
        A = sum(J @ np.swapaxes(J, 1, 2) for J in (Jf[:, 0], Jf[:, 1]))
        M = np.einsum("finp,ficp->fnpc", Jf, JR)
        gf = np.einsum("finp,fip->fn", Jf, r)
        QR = np.einsum("ficp,fidp->fpcd", JR, JR).reshape(F, 9 * P)
        Bp = (_pairs(C).T @ QR).reshape(K, K, P, 3, 3).transpose(2, 0, 3, 1, 4)
        Bp = Bp.reshape(P, 3 * K, -1)
        v = (JR[:, 0] * r[:, 0, None] + JR[:, 1] * r[:, 1, None]).reshape(F, 3 * P)
        gb = (C.T @ v).reshape(K, 3, P).transpose(2, 0, 1).reshape(P, 3 * K)
        A[:, 5:, 5:] += np.diag(self.reg)  # the prior (*), on C and B
        gf[:, 5:] += self.reg * C
        rb = np.repeat(self.reg, 3)
        Bp += np.diag(rb)
        gb += B.transpose(2, 0, 1).reshape(P, 3 * K) * rb
        return A, Bp, M, C, gf, gb

    def step(self, blocks, lam, eta=CG_TOL):
        """The damped step (Marquardt's scaling): the larger of the frames' and the points'
        block sets is eliminated; the basis keeps sum_p dB_p = 0 (a multiplier)."""
        A, Bp, M, C, gf, gb = blocks
        (F, nf), (P, nb) = gf.shape, gb.shape
        dA, dB = _scaling(A, Bp)
        Ad = A + lam * dA[:, :, None] * np.eye(nf) + 1e-15 * np.eye(nf)
        Bd = Bp + lam * dB[:, :, None] * np.eye(nb) + 1e-15 * np.eye(nb)
        if F * nf < P * nb:
            Wc = M.transpose(0, 2, 1, 3)[..., None, :] * C[:, None, None, :, None]
            Wc = Wc.reshape(F, P, nf, nb)
            return self._keep_frames(Ad, Bd, Wc, gf, gb)
        if P * nb >= CG_UNKNOWNS and not self.factorise:
            out = self._keep_points_cg(Ad, Bd, M, C, gf, gb, eta)
            if out is not None:
                return out
            self.factorise = True  # for the rest of this minimise
        return self._keep_points(Ad, Bd, M, C, gf, gb)

    @staticmethod
    def _keep_points_cg(Ad, Bd, M, C, gf, gb, eta):
        """Frames eliminated, the reduced system in the basis solved inexactly: conjugate
        gradients with each point's block of it as preconditioner, in the centred subspace."""
        (F, nf), (P, nb), K = gf.shape, gb.shape, C.shape[1]
        Li, N, h, r = _eliminate_frames(Ad, M, C, gf, gb)
        Nt = np.ascontiguousarray(np.swapaxes(N, 1, 2))
        Nc = np.ascontiguousarray(np.moveaxis(N.reshape(F, nf, P, 3), 3, 1))
        Q = np.einsum("fcip,fdip->fpcd", Nc, Nc)  # each point's 3 x 3 block of N_f' N_f
        Gd = (_pairs(C).T @ Q.reshape(F, 9 * P)).reshape(K, K, P, 3, 3)
        Minv = np.linalg.inv(Bd - Gd.transpose(2, 0, 3, 1, 4).reshape(P, nb, nb))
        Cc = C[:, :, None]

        def Sv(v):  # the Schur complement times v (P, nb)
            V = v.reshape(P, K, 3).transpose(0, 2, 1).reshape(3 * P, K)
            u = Nt @ ((N @ V) @ Cc)  # (F, 3P, 1)
            G = (C.T @ u[..., 0]).reshape(K, P, 3).transpose(1, 0, 2).reshape(P, nb)
            return (Bd @ v[:, :, None])[..., 0] - G

        def precondition(r):
            z = (Minv @ r[:, :, None])[..., 0]
            return z - z.mean(0)

        r -= r.mean(0)
        stop = eta * np.sqrt((r * r).sum())
        d = np.zeros_like(r)
        z = precondition(r)
        p, rz = z.copy(), (r * z).sum()
        for _ in range(CG_MAX_ITER):
            Sp = Sv(p)
            Sp -= Sp.mean(0)
            a = rz / (p * Sp).sum()
            d += a * p
            r -= a * Sp
            if np.sqrt((r * r).sum()) <= stop:
                break
            z = precondition(r)
            rzn = (r * z).sum()
            p, rz = z + rzn / rz * p, rzn
        else:
            return None  # ill-conditioned: the caller factorises
        return _frames_step(Li, N, h, C, d), d

    @staticmethod
    def _keep_frames(Ad, Bd, Wc, gf, gb):
        """Points eliminated: a dense system in the frames' steps and the multiplier nu."""
        (F, nf), (P, nb) = gf.shape, gb.shape
        n = F * nf
        Bi = np.linalg.inv(Bd)
        Q = Wc @ Bi[None]  # W_fp Bd_p^-1
        flat = lambda T: T.transpose(0, 2, 1, 3).reshape(n, P * nb)  # noqa: E731
        H = -(flat(Q) @ flat(Wc).T).reshape(F, nf, F, nf)
        H[np.arange(F), :, np.arange(F), :] += Ad
        U = Q.sum(1).reshape(n, nb)
        S = np.block([[H.reshape(n, n), -U], [-U.T, -Bi.sum(0)]])
        Qg = (Q @ gb[None, :, :, None]).sum(1)[..., 0]
        rhs = np.concatenate([-gf.ravel() + Qg.ravel(), (Bi @ gb[..., None]).sum(0)[..., 0]])
        sol = np.linalg.solve(S, rhs)
        df = sol[:n].reshape(F, nf)
        Wd = (np.swapaxes(Wc, 2, 3) @ df[:, None, :, None]).sum(0)[..., 0]
        db = -(Bi @ (gb + Wd + sol[n:])[..., None])[..., 0]
        return df, db

    @staticmethod
    def _keep_points(Ad, Bd, M, C, gf, gb):
        """Frames eliminated: the Schur complement onto the basis, sum_f (C_f C_f') x (N_f'
        N_f) with N_f = L_f^-1 M_f (its Kronecker form for a large K); the centring by nu."""
        (F, nf), (P, nb), K = gf.shape, gb.shape, C.shape[1]
        Li, N, h, rhs = _eliminate_frames(Ad, M, C, gf, gb)
        n3 = 3 * P
        if K * K >= 2 * nf:  # the Kronecker form costs fewer flops than the full product
            CC, G = _pairs(C), np.zeros((K * K, n3 * n3))
            step = max(1, SCHUR_CHUNK // (n3 * n3))  # frames per chunk: bounded memory
            for i in range(0, F, step):
                Nc = N[i : i + step]
                G += CC[i : i + step].T @ (np.swapaxes(Nc, 1, 2) @ Nc).reshape(len(Nc), -1)
            G = G.reshape(K, K, P, 3, P, 3).transpose(2, 0, 3, 4, 1, 5).reshape(P * nb, -1)
        else:  # one product of the full blocks (F nf, 3KP): faster for a few K
            Nf = (N.reshape(F, nf, P, 1, 3) * C[:, None, None, :, None]).reshape(F * nf, -1)
            G = Nf.T @ Nf
        S = -G  # the Schur complement (SPD: the step is damped)
        S4 = S.reshape(P, nb, P, nb)  # a view
        S4[np.arange(P), :, np.arange(P), :] += Bd
        c = cho_factor(S)
        y = cho_solve(c, rhs.ravel())
        Y = cho_solve(c, np.tile(np.eye(nb), (P, 1)))  # S^-1 E' with E = [I ... I]
        nu = np.linalg.solve(Y.reshape(P, nb, nb).sum(0), y.reshape(P, nb).sum(0))
        db = (y - Y @ nu).reshape(P, nb)  # the centring: sum_p dB_p = 0
        return _frames_step(Li, N, h, C, db), db

    def minimise(self, R, ab, C, B, st, known=(), tol=None, flips=False, bound=None):
        """Levenberg-Marquardt from (R, ab, C, B), the damping updated by the ratio of the
        actual to the predicted decrease (Nielsen 1999): the final state, the history and
        whether it converged; ``None`` for the last where the fit came within ``MERGE_TOL``
        of an answer in ``known`` (camera points, :func:`_camera_points`), whose minimum
        it is reaching. ``flips``: after each step, flip the frames whose other depth order
        has the lower residual (:func:`_depth_orders`; E falls: each frame's term does).
        ``bound``: stop (not converged) where the depth ratio (:func:`depth_ratio`) rises
        above it: the fit has left the answers that can be chosen (:func:`_best`)."""
        E, data = self.cost(R, ab, C, B)
        self.factorise = False
        hist = {"cost": [E], "data_term": [data], "damping": [np.nan]}
        lam, nu, converged, K = 1e-3, 2.0, False, C.shape[1]
        for _ in range(st.max_iter):
            # the inner solve's tolerance falls with E (superlinear near an exact fit)
            eta = min(CG_TOL, np.sqrt(E / hist["cost"][0]))
            blocks = self.normal_equations(R, ab, C, B)
            A, Bp, _, _, gf, gb = blocks
            dA, dB = _scaling(A, Bp)
            while True:
                df, db = self.step(blocks, lam, eta)
                new = (
                    _rodrigues(df[:, :3]) @ R,
                    ab + df[:, 3:5],
                    C + df[:, 5:],
                    B + db.reshape(-1, K, 3).transpose(1, 2, 0),
                )
                En, dn = self.cost(*new)
                # the model's decrease (-g'd + lam d'Dd) / 2 (also for the conjugate
                # gradients' step: its residual is orthogonal to it)
                dD = (dA * df**2).sum() + (dB * db**2).sum()
                pred = 0.5 * (lam * dD - (gf * df).sum() - (gb * db).sum())
                if En < E:
                    break
                if pred <= st.tol * E:  # more damping cannot reach a decrease that counts
                    return (R, ab, C, B), hist, True
                lam, nu = lam * nu, 2 * nu
                if lam > 1e12:  # no step lowers E: a stationary point
                    return (R, ab, C, B), hist, True
            rho, lam_step = ((E - En) / pred if pred > 0 else 0.0), lam
            lam, nu = max(lam * max(1 / 3, 1 - (2 * rho - 1) ** 3), 1e-12), 2.0
            R, ab, C, B = new
            Cb, Bb = _balanced(C, B)
            Eb, db_ = self.cost(R, ab, Cb, Bb)
            if Eb <= En:  # (not at rounding level, where balancing may add to E)
                C, B, En, dn = Cb, Bb, Eb, db_
            flip = np.logical_and(*_depth_orders(self, R, ab, C, B)) if flips else None
            if flip is not None and flip.any():
                R, ab, C, B = _flip((R, ab, C, B), flip)
                En, dn = self.cost(R, ab, C, B)
            # converged: a decrease below tol E by a step close to Gauss-Newton's (a heavily
            # damped step's small decrease is a slow phase, as near a saddle)
            # ; or E at rounding level
            converged = E - En <= (tol or st.tol) * E and lam_step <= MAX_CONVERGED_DAMPING
            converged = converged or En <= ROUNDING_E * self.spread
            E = En
            for k, v in (("cost", E), ("data_term", dn), ("damping", lam)):
                hist[k].append(v)
            if converged or (bound is not None and depth_ratio(R, ab, C, B) > bound):
                break
            if known and _near((R, ab, C, B), known):
                return (R, ab, C, B), hist, None
        return (R, ab, C, B), hist, converged


def _eliminate_frames(Ad, M, C, gf, gb):
    """The frames' blocks eliminated (``Ad_f = L_f L_f'``): ``L_f^-1`` (F, nf, nf),
    ``N_f = L_f^-1 M_f`` (F, nf, 3P), ``h_f = L_f^-1 g_f`` (F, nf) and the reduced system's
    right-hand side ``-g_B + sum_f (C_f x N_f)' h_f`` (P, 3K)."""
    (F, nf), (P, nb), K = gf.shape, gb.shape, C.shape[1]
    Li = np.linalg.inv(np.linalg.cholesky(Ad))
    N = Li @ M.reshape(F, nf, 3 * P)
    h = (Li @ gf[:, :, None])[..., 0]
    u = (np.swapaxes(N, 1, 2) @ h[:, :, None])[..., 0]  # (F, 3P)
    return Li, N, h, -gb + (C.T @ u).reshape(K, P, 3).transpose(1, 0, 2).reshape(P, nb)


def _frames_step(Li, N, h, C, db):
    """The frames' steps (F, nf) given the basis step ``db`` (P, 3K) (back-substitution)."""
    F, P, K = len(C), len(db), C.shape[1]
    D = (C @ db.reshape(P, K, 3).transpose(1, 0, 2).reshape(K, 3 * P)).reshape(F, 3 * P, 1)
    return -(np.swapaxes(Li, 1, 2) @ (h[:, :, None] + N @ D))[..., 0]


def _scaling(A, Bp):
    """Marquardt's scaling: the diagonals of the frames' and the points' blocks, the
    coefficients' and the basis' entries at least ``DAMPING_FLOOR`` times their mean."""
    dA, dB = np.einsum("fii->fi", A), np.einsum("pii->pi", Bp)
    dA[:, 5:] = np.maximum(dA[:, 5:], DAMPING_FLOOR * dA[:, 5:].mean())
    return dA, np.maximum(dB, DAMPING_FLOOR * dB.mean())


def _pairs(C):
    """(F, K * K): the products C_fk C_fl of each frame's coefficients."""
    return (C[:, :, None] * C[:, None, :]).reshape(C.shape[0], -1)


def _balanced(C, B):
    """The factors of X# = C B that minimise the prior of (*) for that X#: X# = U s V',
    C = U s^(1/2), B = s^(1/2) V', the largest singular value first (non-decreasing weights:
    the weighted nuclear norm is the factored prior's minimum; Iglesias et al. 2020). The
    data term does not change; the factored prior's slow valley of equivalent factors goes."""
    K = C.shape[1]
    Qc, Rc = np.linalg.qr(C)
    Qb, Rb = np.linalg.qr(B.reshape(K, -1).T)
    U, s, Vt = np.linalg.svd(Rc @ Rb.T)
    r = np.sqrt(s)
    return (Qc @ U) * r, (r[:, None] * (Vt @ Qb.T)).reshape(B.shape)


def _factors(shapes, K):
    """Balanced rank-K factors C (F, K), B (K, 3, P) of shapes (F, 3, P) (X# = C B)."""
    F, _, P = shapes.shape
    U, s, Vt = np.linalg.svd(shapes.reshape(F, 3 * P), full_matrices=False)
    r = np.sqrt(s[:K])
    return U[:, :K] * r, (r[:, None] * Vt[:K]).reshape(K, 3, P)


def _depth_orders(fit, R, ab, C, B):
    """Per frame: does the other depth order, ``(Rz(pi) R_f, -C_f)`` (the same orthographic
    image), have the lower perspective residual, and does it keep every point ahead?"""
    r, (Yf, _, rf) = fit.residual(R, ab, C, B)[2], fit.residual(_RZ @ R, ab, -C, B)
    lower = np.sum(rf**2, axis=(1, 2)) < np.sum(r**2, axis=(1, 2))
    return lower, np.all(Yf[:, 2] > 0, axis=1)


def _flip(state, flip):
    R, ab, C, B = state
    return np.where(flip[:, None, None], _RZ @ R, R), ab, np.where(flip[:, None], -C, C), B


def _start(rotations, shapes, centroids, K):
    """The start from an orthographic answer (normalised units): rank-K factors of the
    shapes, the image centroids as (a, b)."""
    C, B = _factors(np.asarray(shapes, float), K)
    return np.array(rotations, float), np.array(centroids, float), C, B


def _orders(fit, state):
    """``state`` in three depth orders, each frame ``(R_f, S_f)`` or ``(Rz(pi) R_f, -S_f)``
    (the same orthographic image): the sequence as the orthographic answer has it, every
    frame reversed, and each frame's order with the lower perspective residual at the start
    (a guess where the start's own error exceeds the perspective effect: MoCap shapes);
    the distinct ones with every point in front of the cameras. The fits from them decide
    (:func:`_fit_orders` re-chooses each frame's order at an answer)."""
    lower, ahead = _depth_orders(fit, *state)
    out = []
    for flip in (np.zeros_like(ahead), ahead, lower & ahead):
        if not any(np.array_equal(flip, f) for f, _ in out):
            out.append((flip, _flip(state, flip)))
    return [s for _, s in out if np.isfinite(fit.cost(*s)[0])]


def _fit_orders(fit, state, st, say=None, what="fit", known=()):
    """Minimise (*) from ``state`` to ``LOOSE_TOL`` in the start's depth orders; where another
    order lowers a frame's residual at the answer, flip those frames and minimise again, each
    frame's order now re-chosen after every step (:meth:`_Fit.minimise` ``flips``; the order
    is discrete, the fit continuous), at most ``MAX_FLIP_ROUNDS`` times; a fit whose depth
    ratio rises above ``MAX_DEPTH_RATIO`` stops there. ``say(message)``: progress. Returns
    (state, history, converged), or None where the fit came near an answer in ``known``
    (:meth:`_Fit.minimise`); :func:`_polish` takes it on to ``st.tol``."""
    loose = max(st.tol, LOOSE_TOL)
    n = 0
    for round_ in range(MAX_FLIP_ROUNDS + 1):
        flips = round_ > 0  # the start's orders are its hypothesis: held through one fit
        state, hist, converged = fit.minimise(
            *state, st, known, tol=loose, flips=flips, bound=MAX_DEPTH_RATIO
        )
        n += len(hist["cost"]) - 1
        if converged is None or depth_ratio(*state) > MAX_DEPTH_RATIO:
            break
        flip = np.logical_and(*_depth_orders(fit, *state))
        if not flip.any() or round_ == MAX_FLIP_ROUNDS:
            break
        state = _flip(state, flip)
    out = None if converged is None else (state, hist, converged)
    if say is not None:
        end = "near an earlier answer" if out is None else f"E {hist['cost'][-1]:.4g}"
        say(f"perspective {what}: {n} iterations, {end}")
    return out


def _fits(fit, starts, st, say=None, out=None):
    """:func:`_fit_orders` from each of ``starts`` (name -> (what, state)); a fit that comes
    near an earlier one's answer (or one in ``out``) stops there and is left out: ``out``
    with the new fits added, name -> (state, history, converged)."""
    out = {} if out is None else dict(out)
    known = [_camera_points(r[0]) for r in out.values()]
    for name, (what, s0) in starts.items():
        r = _fit_orders(fit, s0, st, say, what, known)
        if r is not None:
            out[name] = r
            known.append(_camera_points(r[0]))
    return out


def _polished(fit, fits, st, say=None, what="fit from"):
    """``fits`` (name -> fit of :func:`_fit_orders`) with those within ``MAX_DEPTH_RATIO``
    whose E is within ``POLISH_MARGIN`` of the lowest of them taken on to ``st.tol`` (a fit
    that leaves the ratio stops); where none is within it, those near the lowest of all,
    without the bound."""
    within = {n: f for n, f in fits.items() if depth_ratio(*f[0]) <= MAX_DEPTH_RATIO}
    pool, bound = (within, MAX_DEPTH_RATIO) if within else (fits, None)
    E0 = min(f[1]["cost"][-1] for f in pool.values())
    out = dict(fits)
    for name, f in pool.items():
        if f[1]["cost"][-1] <= (1 + POLISH_MARGIN) * E0:
            out[name] = _polish(fit, f, st, say, f"{what} {name}", bound)
    return out


def _polish(fit, out, st, say=None, what="fit", bound=None):
    """A fit of :func:`_fit_orders` taken on to ``st.tol`` in its depth orders; one history
    (``out`` with history None: the fit from its state)."""
    state, hist, _ = out
    state, more, converged = fit.minimise(*state, st, bound=bound)
    hist = more if hist is None else {k: hist[k] + more[k][1:] for k in hist}
    if say is not None:
        n, E = len(more["cost"]) - 1, hist["cost"][-1]
        say(f"perspective {what} to tol: {n} iterations, E {E:.4g}")
    return state, hist, converged


def _continuation(one, rank_one, X0, K, st, say=None):
    """The continuation's start: the rank-1 fit (``one``, :func:`_fits` from the depth orders
    of the rank-1 orthographic answer ``rank_one``) with K - 1 small columns in the
    directions of the rank-K answer's shapes ``X0``; None where every order puts points
    behind the camera."""
    starts = _orders(one, _start(*rank_one, 1))
    if not starts:
        return None
    fits = _fits(one, {i: ("rank-1 fit", s1) for i, s1 in enumerate(starts)}, st, say)
    R1, ab1, C1, B1 = _best(list(fits.values()))[0]
    _, Bd = _factors(X0, K)
    Bn = _SMALL * np.linalg.norm(B1) * Bd[1:] / np.linalg.norm(Bd[1:], axis=(1, 2))[:, None, None]
    Cn = np.full((len(C1), K - 1), _SMALL * np.linalg.norm(C1) / np.sqrt(len(C1)))
    return R1, ab1, np.column_stack([C1, Cn]), np.concatenate([B1, Bn])


def depth_ratio(R, ab, C, B):
    """The largest ratio of two points' depths in one frame of an answer of (*)."""
    Z = _camera_points((R, ab, C, B))[:, 2]
    return float(np.max(Z.max(axis=1) / Z.min(axis=1)))


def _best(fits):
    """The fit of the lowest E among those within ``MAX_DEPTH_RATIO`` (all, if none is)."""
    within = [f for f in fits if depth_ratio(*f[0]) <= MAX_DEPTH_RATIO] or fits
    return min(within, key=lambda f: f[1]["cost"][-1])


def _camera_points(state):
    """(F, 3, P): the points in each camera of an answer of (*)."""
    R, ab, C, B = state
    Y = R @ (C @ B.reshape(len(B), -1)).reshape(len(C), 3, -1)
    Y[:, :2] += ab[:, :, None]
    Y[:, 2] += 1.0
    return Y


def _near(state, known):
    """Is ``state`` within ``MERGE_TOL`` of one of the camera points ``known``?"""
    Y = _camera_points(state)
    return any(np.linalg.norm(Y - Yk) <= MERGE_TOL * np.linalg.norm(Yk) for Yk in known)


def _noise(fit, state, K):
    """RMS image noise from the residual of the fit without prior (*), per degree of freedom:
    the data term's share of W that the model cannot explain (0 on exact data)."""
    F, P = fit.m.shape
    n_obs = 2 * float(fit.m.sum())
    n_par = F * (5 + K) + 3 * K * P - 3 * K - K * K - 3  # minus centring, C-B mixing, rotation
    return float(np.sqrt(2 * fit.cost(*state)[1] / max(n_obs - n_par, 1.0)))


def refine_perspective(
    x,
    K,
    direct,
    rank_one=None,
    weights=None,
    sigma_1=None,
    *,
    intrinsics,
    observed=None,
    settings=None,
    progress=None,
):
    """Refine orthographic answers under the pinhole model (*) (module docstring).

    The prior's balance comes from W: the best fit without prior gives the noise level (its
    residual per degree of freedom), and mu is the bilinear shape stage's rule of that noise
    (:class:`nrsfm.BilinearSettings`: ``mu_factor``, ``mu_noise``); on exact data both are
    zero and the answer is exact.

    Parameters
    ----------
    x : (F, 2, P) ndarray
        Normalised image coordinates (:func:`normalise`); NaN where not seen.
    K : int
    direct : tuple (rotations (F, 3, 3), shapes (F, 3, P), centroids (F, 2))
        The rank-K orthographic answer on ``x``: shapes in the units of x, centred.
    rank_one : tuple, callable returning one, or None
        The same at K = 1 (the continuation's start), called only where the continuation
        is run (the direct starts reach more than one minimum); None: no continuation.
    weights : (K,) array_like or None
        The prior's weights ``a_k`` (:func:`nrsfm.stages.shape.bilinear.bilinear_weights`);
        None: no prior (the method ``pseudo_inverse``).
    sigma_1 : float
        The largest singular value of the orthographic ``X_init#`` (units of x), for mu.
    intrinsics : (3, 3) array_like
    observed : (F, P) bool ndarray, optional
        Where a point was seen (default: where x is finite).
    settings : PerspectiveSettings, optional
    progress : callable, optional
        Called with a message after each fit.

    Returns
    -------
    PerspectiveResult
    """
    from .shape.bilinear import BilinearSettings

    st = settings or PerspectiveSettings()
    A = check_intrinsics(intrinsics)
    F, _, P = x.shape
    seen = np.isfinite(x).all(axis=1) if observed is None else np.asarray(observed, bool)
    m = seen.astype(float)
    xs = np.where(seen[:, None], x, 0.0)
    R0, X0, c0 = (np.asarray(v, float) for v in direct)
    free = _Fit(xs, m, np.zeros(K))
    starts = _orders(free, _start(R0, X0, c0, K))
    if not starts:
        raise ValueError(
            "the orthographic answer puts points behind the camera in either depth order: "
            "check the intrinsics (the focal length in pixels, the principal point)"
        )
    names = ("direct", "direct 2", "direct 3")
    todo = {
        n: (f"fit without prior, start {i + 1}", s0) for i, (n, s0) in enumerate(zip(names, starts))
    }
    fits = _fits(free, todo, st, progress)  # the distinct minima without prior
    if len(fits) > 1 and K > 1 and rank_one is not None:  # they disagree: the continuation
        rank_one = rank_one() if callable(rank_one) else rank_one
        s0 = _continuation(_Fit(xs, m, np.zeros(1)), rank_one, X0, K, st, progress)
        if s0 is not None:
            todo = {"continuation": ("fit without prior from the rank-1 fit", s0)}
            fits = _fits(free, todo, st, progress, fits)
    fits = _polished(free, fits, st, progress, "fit without prior from")
    best_free = min(fits.values(), key=lambda f: f[1]["cost"][-1])
    noise = _noise(free, best_free[0], K)  # the best fit measures it
    bal = BilinearSettings()
    mu = max(
        bal.mu_factor * noise * (np.sqrt(F) + np.sqrt(3 * P)),
        bal.mu_noise * noise**2 * (F + 2 * P) / max(float(sigma_1 or 0.0), 1e-300),
    )
    reg = mu * (np.zeros(K) if weights is None else np.asarray(weights, float))
    what = "fit with the prior from"
    if np.any(reg) and len(fits) > 1:  # from each distinct minimum without it, compared
        fit = _Fit(xs, m, reg)
        todo = {k: (f"{what} {k}", v[0]) for k, v in fits.items()}
        runs = _polished(fit, _fits(fit, todo, st, progress), st, progress, what)
    elif np.any(reg):  # one minimum: its fit with the prior straight on to st.tol
        fit, ((k, v),) = _Fit(xs, m, reg), fits.items()
        bound = MAX_DEPTH_RATIO if depth_ratio(*v[0]) <= MAX_DEPTH_RATIO else None
        runs = {k: _polish(fit, (v[0], None, None), st, progress, f"{what} {k}", bound)}
    else:  # no prior (K = 1: a_1 = 0): the fits without it are the answers
        runs = {k: (v[0], {n: h[-1:] for n, h in v[1].items()}, v[2]) for k, v in fits.items()}
    objectives = {k: v[1]["cost"][-1] for k, v in runs.items()}
    best = next(k for k, v in runs.items() if v is _best(list(runs.values())))  # first: tie
    (R, ab, C, B), hist, converged = runs[best]
    # the answer's path: its fit without prior (in its last depth orders), then the prior's
    prior = np.r_[np.zeros(len(fits[best][1]["cost"])), np.ones(len(hist["cost"]) - 1)]
    hist = {k: fits[best][1][k] + hist[k][1:] for k in hist}
    hist["prior"] = prior
    S = np.einsum("fk,kcp->fcp", C, B)
    t = np.column_stack([ab, np.ones(F)])
    u = _pixels(xs, A)

    def rms(proj):  # pixels, over the observed points
        d = (_pixels(proj, A) - u) * m[:, None]
        return float(np.sqrt(np.sum(d**2) / max(m.sum(), 1.0)))

    Y = R @ S + t[:, :, None]
    return PerspectiveResult(
        rotations=R,
        translations=t,
        shapes=S,
        intrinsics=A,
        start=best,
        objectives=objectives,
        noise=noise,
        mu=mu,
        reg=reg,
        history={k: np.asarray(v) for k, v in hist.items()},
        n_iter=len(hist["cost"]) - 1,
        converged=converged,
        depth_ratio=depth_ratio(R, ab, C, B),
        tol=st.tol,
        reprojection_before=rms(R0[:, :2] @ X0 + c0[:, :, None]),
        reprojection_after=rms(Y[:, :2] / Y[:, 2:3]),
    )

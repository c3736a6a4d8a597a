"""How much a track's filled entries amplify measurement noise: the fill gain.

A track seen in a few frames only is filled by an extrapolation whose noise gain grows
without bound as its observed frames shrink; above :data:`MAX_GAIN` the data do not pin
the track down (it is *undetermined*: filled, but its 3D cannot be trusted).
"""

from __future__ import annotations

import numpy as np

__all__ = ["MAX_GAIN", "fill_gain", "mask_groups", "normal_matrices"]

#: A track is "determined" when its fill amplifies measurement noise at most this much
#: (see :func:`fill_gain`).
MAX_GAIN = 3.0


def mask_groups(obs):
    """Points that share an observation pattern of ``obs`` (F, P): ``(patterns (U, F)
    bool, index (P,))``, with ``patterns[index] == obs.T``."""
    packed = np.packbits(obs.T, axis=1)
    _, first, index = np.unique(packed, axis=0, return_index=True, return_inverse=True)
    return obs[:, first].T, index.ravel()


def normal_matrices(M, patterns):
    """``(Mf, A)``: M (2F, r) as (F, 2, r) row pairs, and the (U, r, r) normal matrices
    ``A_u = sum_{f observed} M_f' M_f`` of the observation patterns (U, F) bool."""
    F2, r = M.shape
    Mf = M.reshape(F2 // 2, 2, r)
    G = np.einsum("fir,fis->frs", Mf, Mf).reshape(F2 // 2, r * r)
    return Mf, (patterns.astype(float) @ G).reshape(-1, r, r)


def fill_gain(M, observed):
    """Noise gain of each track's filled entries (unitless, scale-free).

    A point's structure column b_p is fitted to the frames that observe it, normal matrix
    ``A_p = sum_{f observed} M_f' M_f``; the fill ``M_f b_p`` of a frame then has
    covariance ``sigma^2 M_f A_p^{-1} M_f'`` for white measurement noise sigma. The gain
    is ``max_f sqrt(lambda_max(M_f A_p^{-1} M_f'))`` over all frames: at most 1 inside the
    observed frames of a complete track, large when a short track is extrapolated.

    Parameters
    ----------
    M : (2F, r) ndarray
    observed : (F, P) bool ndarray

    Returns
    -------
    gain : (P,) ndarray
    """
    F2 = M.shape[0]
    observed = np.asarray(observed, dtype=bool)
    if observed.shape[0] * 2 != F2:
        raise ValueError(f"observed must have shape (F, P) with 2F = {F2}; "
                         f"got {observed.shape}")
    patterns, index = mask_groups(observed)
    Mf, A = normal_matrices(M, patterns)
    Ai = np.linalg.pinv(A, hermitian=True)                    # (U, r, r)
    lev = np.einsum("fir,urs,fjs->ufij", Mf, Ai, Mf)           # (U, F, 2, 2)
    gain = np.sqrt(np.clip(np.linalg.eigvalsh(lev)[..., -1], 0.0, None).max(axis=1))
    w = np.linalg.eigvalsh(A)
    gain[w[:, 0] <= 1e-12 * w[:, -1]] = np.inf                # b_p not determined at all
    return gain[index]

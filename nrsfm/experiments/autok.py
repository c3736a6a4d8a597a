"""Automatic K from W alone: a rule on the singular value spectrum of W.

Rule: the rank r of W (row-centred; its completion when observations are missing) is the
number of singular values above ``max(RELATIVE_FLOOR sigma_1, tau_GD)``, where tau_GD is
Gavish & Donoho's optimal hard threshold for white noise of unknown level ("The optimal
hard threshold for singular values is 4/sqrt(3)", IEEE Trans. Inf. Theory 2014):
``tau_GD = omega(beta) median(sigma)``, ``omega(beta) ~ 0.56 beta^3 - 0.95 beta^2 +
1.82 beta + 1.43``, ``beta = min(2F, P) / max(2F, P)``. The relative floor counts model
error and round-off as noise where the data has no measurement noise (the MoCap files).
Then ``K = ceil(r / 3)`` (W has rank 3K under the model W = R S, paper Eq. 1), clipped to
``1 <= K <= min(2F, P) // 3``. Measurements (MoCap K sweep; synthetic sequences with known K
and noise) are in ``docs/experiments.md``.
"""

from __future__ import annotations

import math

import numpy as np

__all__ = ["choose_K", "gavish_donoho_threshold", "RELATIVE_FLOOR"]

#: singular values below this fraction of sigma_1 count as model error / round-off
RELATIVE_FLOOR = 1e-3


def gavish_donoho_threshold(s, shape):
    """Gavish & Donoho's hard threshold for singular values ``s`` of a matrix of ``shape``,
    noise level unknown: ``omega(beta) median(s)``."""
    m, n = sorted(shape)
    beta = m / n
    omega = 0.56 * beta ** 3 - 0.95 * beta ** 2 + 1.82 * beta + 1.43
    return float(omega * np.median(s))


def choose_K(W, relative_floor=RELATIVE_FLOOR):
    """Number of shape bases K from the spectrum of W.

    Parameters
    ----------
    W : (2F, P) or (F, 2, P) array_like
        Measurements (NaN = missing: then the completed W is used).
    relative_floor : float
        In (0, 1): singular values at or below ``relative_floor * sigma_1`` are ignored.

    Returns
    -------
    K : int
    info : dict
        ``rank`` (r), ``singular_values`` (of the centred W, divided by sigma_1),
        ``threshold`` (relative to sigma_1), ``gavish_donoho`` (relative), ``K_max``.

    Raises
    ------
    ValueError
        Bad W (see :func:`nrsfm.validation.check_measurements`), bad floor.
    """
    from ..validation import check_measurements
    from ..stages.measurement import centre_rows

    if not (0 < relative_floor < 1):
        raise ValueError(f"relative_floor must be in (0, 1); got {relative_floor!r}")
    W = check_measurements(W, allow_missing=True)
    if np.isnan(W).any():
        from ..stages.completion import complete_measurements

        W = complete_measurements(W).W
    Wc, _ = centre_rows(W)
    s = np.linalg.svd(Wc, compute_uv=False)
    if not s[0] > 0:
        raise ValueError("W is constant after centring: no rank to estimate")
    s = s / s[0]
    gd = gavish_donoho_threshold(s, Wc.shape)
    thr = max(relative_floor, gd)
    r = int(np.count_nonzero(s > thr))
    K_max = min(W.shape) // 3
    K = int(min(max(1, math.ceil(r / 3)), K_max))
    return K, dict(rank=r, singular_values=s, threshold=thr, gavish_donoho=gd, K_max=K_max)

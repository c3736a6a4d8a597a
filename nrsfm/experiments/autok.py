"""Automatic K from W alone: a rule on the singular value spectrum of W.

Rule: the rank r of W is the number of singular values above ``RELATIVE_FLOOR x sigma_1``
(of the row-centred W, or of its completion when observations are missing), and
``K = ceil(r / 3)`` (W has rank 3K under the model W = R S, paper Eq. 1), clipped to the
admissible range ``1 <= K <= min(2F, P) // 3``. The floor and how it was chosen (MoCap K
sweep, checked on synthetic sequences with known K and noise) are in
``docs/experiments.md``.
"""

from __future__ import annotations

import math

import numpy as np

__all__ = ["choose_K", "RELATIVE_FLOOR"]

#: singular values below this fraction of sigma_1 count as noise / model error
RELATIVE_FLOOR = 1e-2


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
        ``K_max``.

    Raises
    ------
    ValueError
        Bad W (see :func:`nrsfm._validation.check_measurements`), bad floor.
    """
    from .._validation import check_measurements
    from ..measurement import centre_rows

    if not (0 < relative_floor < 1):
        raise ValueError(f"relative_floor must be in (0, 1); got {relative_floor!r}")
    W = check_measurements(W, allow_missing=True)
    if np.isnan(W).any():
        from ..completion import complete_measurements

        W = complete_measurements(W).W
    Wc, _ = centre_rows(W)
    s = np.linalg.svd(Wc, compute_uv=False)
    if not s[0] > 0:
        raise ValueError("W is constant after centring: no rank to estimate")
    s = s / s[0]
    r = int(np.count_nonzero(s > relative_floor))
    K_max = min(W.shape) // 3
    K = int(min(max(1, math.ceil(r / 3)), K_max))
    return K, dict(rank=r, singular_values=s, K_max=K_max)

"""Scale normalisation of W (the shape-stage thresholds are not scale invariant).

PROVISIONAL rule, to be replaced by the shape-stage study (issue 3): divide W by its mean
row standard deviation, times a constant.
"""

from __future__ import annotations

import numpy as np

__all__ = ["normalization_scale"]

TARGET_ROW_STD = 1.2


def normalization_scale(W):
    """Scale s such that ``W / s`` is in the units the shape stage's constants assume.

    Parameters
    ----------
    W : (2F, P) ndarray
        Row-centred measurements.

    Returns
    -------
    s : float
        Positive; ``reconstruct`` divides W by s and multiplies the shapes by s.
    """
    row_std = float(np.mean(np.std(W, axis=1)))
    if not row_std > 0:
        raise ValueError("W is constant (every row has zero spread): nothing to reconstruct")
    return row_std / TARGET_ROW_STD

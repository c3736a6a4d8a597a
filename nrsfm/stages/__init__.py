"""The method's stages, in the paper's order.

``measurement`` (centring, rank-3K SVD) -> ``completion`` (missing data, when any) ->
``corrective`` (the K corrective triplets G^k) -> ``rotations`` (K rotations per frame,
registration, filtering, L1 averaging) -> ``shape`` (pseudo-inverse X_init, then the
low-rank shape by one of the solvers). :func:`nrsfm.reconstruct` composes them.
"""

"""Quality signals of a reconstruction, each with the threshold that flags it.

``nrsfm.reconstruct`` attaches a :class:`Diagnostics` to every result
(``Reconstruction.diagnostics``) and issues one :class:`NRSfMWarning` when a signal crosses
its threshold. The signals are measured from W and the rotation stage only (never from
ground truth). Thresholds and the measurements behind them: ``docs/rotation_stage.md``;
every flag and note, its message and what to do: ``docs/warnings.md``
(:mod:`nrsfm.warnings_catalog`).

Signals (name: meaning; flagged when)
-------------------------------------
* ``numerical_rank``: number of singular values of the centred W above
  ``RANK_RTOL * s_1``; below 3K the rank-3K model has directions with no data (a planar
  object with K too large; a static camera, whose W has rank at most 2K). Flagged when
  another signal is flagged too (it is then the likely cause) or the rotations were
  given; otherwise a note: shark has rank 5 < 3K = 9 and is reconstructed at the
  published accuracy, its triplet confirmed at noise level.
* ``rank_gap``: ``s_3K / s_3K+1``; a note below ``RANK_GAP_MIN`` (3K cuts inside the
  noise floor of the singular values), not a flag: on pickup, drink, yoga and dance with
  track noise of 5% or more the gap is 1.004-1.027 while the rotations stay accurate.
* ``condition``: ``s_1 / s_3K`` of W, the condition of the factorisation; flagged above
  ``CONDITION_MAX``.
* ``triplet_cost_ratio``: Dai's cost of the best triplet divided by the cost the noise
  level of W predicts (:func:`predicted_triplet_cost`); flagged above
  ``COST_RATIO_MAX`` (the triplet search ended in a bad minimum, or W is not an
  orthographic measurement matrix, e.g. transposed).
* ``kept_fraction``: fraction of the rotation samples that passed the filter; flagged
  below ``KEPT_MIN`` (the K samples per frame disagree).
* ``smoothness_sign_fraction``: fraction of frames whose depth sign the motion-smoothness
  rule changed; above ``SIGN_FRACTION_MAX`` (the estimated cameras jump by more than 90
  degrees between frames) a flag when another signal is flagged too or W has rank below
  3K, a note otherwise
  (a camera that really jumps: the depth sign of a frame, a mirror image of its shape,
  is not determined by an orthographic camera).
* ``triplet_hits``: starts of the triplet search that reached its best minimum; flagged
  below 2 (the best minimum was never confirmed).
* ``camera_spread_deg``: largest angle (degrees) between a frame's estimated viewing
  direction (third row of R_f, up to the depth sign) and their mean; flagged below
  ``CAMERA_SPREAD_MIN_DEG`` (a nearly static camera: depth is not observed).
* ``depth_amplification``: how much more the cameras leave the depth of the shapes'
  deformation modes open than cameras from all directions would
  (:func:`nrsfm.metrics.depth_amplification`, from the rotations and shapes of the run,
  given rotations included, W with 3K directions only, not for the pseudo-inverse);
  flagged above ``DEPTH_AMPLIFICATION_MAX`` when W has more than rounding beyond its
  rank-3K part (``DEPTH_NOISE_MIN``), or when infinite (the camera motion does not
  determine the depth of the deformation: a limit of the data, not a failed search).
* ``triplet_cost_ratio`` above ``COST_RATIO_MAX`` is a flag only when other random starts
  reach a lower cost (a failed search, :func:`nrsfm.stages.rotations.subspace.lower_minimum`);
  otherwise a note (the rank-3K model does not fit W exactly, as with real shapes).
* ``looks_transposed``: Dai's cost per frame of W is much higher than that of ``W'``
  read as measurements (only computed when the cost ratio is flagged and ``W'`` has an
  even number of rows).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from .stages.rotations.subspace import DETERMINED_RTOL, lower_minimum
from .warnings_catalog import UNRELIABLE, text

__all__ = ["NRSfMWarning", "Diagnostics", "THRESHOLDS", "RANK_RTOL", "RANK_GAP_MIN",
           "CONDITION_MAX", "COST_RATIO_MAX", "CAMERA_SPREAD_MIN_DEG", "KEPT_MIN", "SIGN_FRACTION_MAX",
           "DEPTH_AMPLIFICATION_MAX", "DEPTH_NOISE_MIN",
           "predicted_triplet_cost", "numerical_rank", "diagnose"]

#: singular values below ``RANK_RTOL * s_1`` count as zero (the rotation stage's tolerance
#: for the determined subspace, :mod:`nrsfm.stages.rotations.subspace`)
RANK_RTOL = DETERMINED_RTOL
#: smallest acceptable ``s_3K / s_3K+1``
RANK_GAP_MIN = 1.02
#: largest acceptable ``s_1 / s_3K``
CONDITION_MAX = 1e6
#: largest acceptable ratio of Dai's cost to the cost the noise level predicts
COST_RATIO_MAX = 4.0
#: smallest acceptable fraction of rotation samples kept by the filter
KEPT_MIN = 0.5
#: largest acceptable fraction of frames whose depth sign came from smoothness
SIGN_FRACTION_MAX = 0.10

#: largest acceptable ``nrsfm.metrics.depth_amplification`` (1 for cameras from all
#: directions); measured (docs/rotation_stage.md, section 9): at most 4.85 on the runs with
#: e3d < .03 but drink on a 145-degree path (8.7, 25.9), at least 12.5 on the runs of
#: pickup, stretch, drink and back with e3d > 0.1; the threshold is their geometric middle
DEPTH_AMPLIFICATION_MAX = 8.0
#: ... when W has more than rounding beyond its rank-3K part (``noise_level`` above this):
#: the amplification multiplies what the model does not explain, and an exactly rank-3K W
#: with finite amplification has one exact answer (noise-free rank-K shapes on a smooth
#: camera: 8.9, e3d 1e-9)
DEPTH_NOISE_MIN = 1e-10

#: smallest acceptable largest angle between a viewing direction and their mean (degrees)
CAMERA_SPREAD_MIN_DEG = 10.0
#: absolute floor (per frame) of the predicted triplet cost: keeps the ratio finite on
#: noise-free data
COST_FLOOR_PER_FRAME = 1e-6
#: W "looks transposed" when read as (P, 2F) its best Dai cost per frame is below this
#: fraction of the cost per frame as given
TRANSPOSE_RATIO = 0.25

THRESHOLDS = dict(camera_spread_deg=f"< {CAMERA_SPREAD_MIN_DEG}",numerical_rank="< 3K (note unless another flag)",
                  rank_gap=f"< {RANK_GAP_MIN} (note)",
                  condition=f"> {CONDITION_MAX:g}", triplet_cost_ratio=f"> {COST_RATIO_MAX}",
                  kept_fraction=f"< {KEPT_MIN}",
                  smoothness_sign_fraction=f"> {SIGN_FRACTION_MAX}",
                  triplet_hits="< 2", looks_transposed="True",
                  depth_amplification=f"> {DEPTH_AMPLIFICATION_MAX} with noise_level > "
                                      f"{DEPTH_NOISE_MIN:g}")


class NRSfMWarning(UserWarning):
    """A reconstruction whose quality signals say it is unreliable (see ``diagnostics``).

    Its message is ``"unreliable reconstruction: "`` and the run's flags, each starting with
    its id (``W-...``, ``docs/warnings.md``), separated by ``"; "``."""


@dataclass
class Diagnostics:
    """Measured quality signals of one run.

    Attributes
    ----------
    signals : dict
        Signal name -> measured value (see the module docstring).
    flags : list of str
        One message per signal that crossed its threshold, starting with its id
        (``W-...``, ``docs/warnings.md``): what is wrong (with the measured value and the
        threshold), what it means for the result and what to try. Empty for a run with
        nothing to report.
    notes : list of str
        Observations that need no action (ids ``N-...``, ``docs/warnings.md``; a
        rank-deficient W whose best triplet is confirmed and fits at the noise level).
    thresholds : dict
        Signal name -> the rule that flags it.
    """

    signals: dict = field(default_factory=dict)
    flags: list = field(default_factory=list)
    notes: list = field(default_factory=list)
    thresholds: dict = field(default_factory=lambda: dict(THRESHOLDS))

    @property
    def flagged(self):
        return bool(self.flags)

    def summary(self):
        """Lines ``name value (flag rule)`` and the flags, for reports."""
        lines = []
        for k, v in self.signals.items():
            val = f"{v:.4g}" if isinstance(v, (float, np.floating)) else str(v)
            lines.append(f"{k} = {val} (flagged when {self.thresholds.get(k, '-')})")
        lines += [f"note: {n}" for n in self.notes]
        lines += [f"WARNING: {f}" for f in self.flags]
        return "\n".join(lines)

    @property
    def message(self):
        """The one warning a flagged run raises (:class:`NRSfMWarning`), or None."""
        return UNRELIABLE + "; ".join(self.flags) if self.flags else None


# ----------------------------------------------------------------------------- signals
def numerical_rank(singular_values, rtol=RANK_RTOL):
    """Number of singular values above ``rtol * s_1``."""
    s = np.asarray(singular_values, float)
    if s.size == 0 or s[0] <= 0:
        return 0
    return int(np.sum(s > rtol * s[0]))


def predicted_triplet_cost(M_hat, G, singular_values, sigma):
    """Dai's cost that noise of std ``sigma`` on W alone produces at the true triplet.

    First order: ``M_hat = W V S^-1/2``, so noise on W puts noise of covariance
    ``sigma^2 G' S^-1 G`` on each row of ``M_f G``; with per-coordinate variance
    ``s^2 = sigma^2 ||S^-1/2 G||_F^2 / 3`` each of the two residuals of frame f has
    variance ``8 s^2 / c_f^2`` (``c_f^2`` the mean squared row norm of ``M_f G``), so the
    expected cost is ``sum_f 16 s^2 / c_f^2``.
    """
    M = np.asarray(M_hat, float)
    G = np.asarray(G, float)
    r = M.shape[1]
    s = np.asarray(singular_values, float)[:r]
    live = s > RANK_RTOL * s[0]                # rows W does not determine carry no noise
    s2 = sigma ** 2 * np.sum(G[live] ** 2 / s[live, None]) / 3.0
    B = (M @ G).reshape(-1, 2, 3)
    c2 = 0.5 * np.sum(B ** 2, axis=(1, 2))
    c2 = np.maximum(c2, 1e-12 * max(np.median(c2), 1e-300))
    return float(np.sum(16.0 * s2 / c2))


def _dai_cost_per_frame(Wc, K, seed=0):
    """Best Dai cost per frame of a centred measurement matrix (for the transpose test)."""
    from .stages.corrective import corrective_triplets
    from .stages.measurement import factorize

    fact = factorize(Wc / max(np.linalg.norm(Wc), 1e-300), K)
    cor = corrective_triplets(fact.M_hat, K, seed=seed, max_starts=6)
    return float(cor.costs[0]) / (Wc.shape[0] // 2)


def diagnose(W, K, factorization, rotation_stage=None, seed=0, depth_amplification=None):
    """Measure the quality signals of a run and flag those beyond their thresholds.

    Parameters
    ----------
    W : (2F, P) ndarray
        Row-centred measurements (any scale).
    K : int
    factorization : nrsfm.stages.measurement.Factorization
        The rank-3K factorisation of W (its singular values, noise level and motion
        factor M_hat).
    rotation_stage : RotationResult, optional
        None when the rotations were given.
    seed : int
        For the transpose test's triplet search.
    depth_amplification : float, optional
        :func:`nrsfm.metrics.depth_amplification` of the run's rotations (estimated or
        given) and shapes (the pipeline measures it: it needs the shapes, which the
        diagnostics do not see); None: no depth signal.

    Returns
    -------
    Diagnostics
    """
    W = np.asarray(W, float)
    twoF, P = W.shape
    F = twoF // 2
    r = 3 * K
    s = np.asarray(factorization.singular_values, float)
    M_hat = factorization.M_hat
    sig, flags = {}, []

    rank = numerical_rank(s)
    sig["numerical_rank"] = rank
    rank_msg = None
    if rank < r:
        rank_msg = text("W-rank-deficient", rank=rank, K=K, r=r, rtol=RANK_RTOL)
    nxt = s[r] if s.size > r else 0.0
    gap = float(s[r - 1] / nxt) if nxt > 0 else np.inf
    sig["rank_gap"] = gap
    notes = []
    if rank >= r and gap < RANK_GAP_MIN:
        notes.append(text("N-no-rank-gap", r=r, gap=gap, gap_min=RANK_GAP_MIN))
    cond = float(s[0] / s[r - 1]) if s[r - 1] > 0 else np.inf
    sig["condition"] = cond
    if rank >= r and cond > CONDITION_MAX:
        flags.append(text("W-ill-conditioned", cond=cond, cond_max=CONDITION_MAX))
    sigma = factorization.noise_level
    rms = np.sqrt(np.sum(s ** 2) / (twoF * P))
    sig["noise_level"] = sigma / rms if rms > 0 else 0.0     # relative to W's RMS entry

    if rank >= r:
        _depth_signal(depth_amplification, sig, flags)
    if rotation_stage is not None:
        _rotation_signals(W, K, s, sigma, M_hat, rotation_stage, seed, rank >= r, sig, flags,
                          notes)
    if rank_msg is not None:
        # A rank-deficient W with a confirmed, noise-level triplet is not by itself a failure
        # (shark: rank 5 < 3K = 9, e3d at the paper's level): a note then, a flag (and the
        # named cause of the other flags) otherwise.
        if flags or rotation_stage is None:
            flags.insert(0, rank_msg)
        else:
            notes.append(text("N-rank-deficient-subspace", rank=rank, r=r,
                              k_eff=rotation_stage.effective_K, K=K))
    return Diagnostics(signals=sig, flags=flags, notes=notes)


def _cost_signals(K, s, sigma, M_hat, rotation_stage, seed, sig, flags, notes):
    """Dai's cost of the best triplet against the noise prediction: a flag when other
    random starts reach a lower cost (a failed search), a note otherwise (the rank-3K model
    does not fit W exactly, as with real shapes). Returns (cost, ratio)."""
    F = M_hat.shape[0] // 2
    cost = float(rotation_stage.search.costs[0])
    pred = predicted_triplet_cost(M_hat, rotation_stage.G[0], s, sigma)
    # noise-free data: a small absolute floor keeps the ratio finite and meaningful
    ratio = cost / max(pred, COST_FLOOR_PER_FRAME * F)
    sig.update(triplet_cost=cost, triplet_cost_predicted=pred, triplet_cost_ratio=ratio)
    if ratio <= COST_RATIO_MAX:
        return cost, ratio
    lower, other = lower_minimum(M_hat, K, cost, seed)
    sig["triplet_cost_other_starts"] = other
    if lower:
        flags.append(text("W-triplet-bad-minimum", cost=cost, ratio=ratio, pred=pred,
                          ratio_max=COST_RATIO_MAX, other=other))
    else:
        notes.append(text("N-model-misfit", cost=cost, ratio=ratio, pred=pred, r=3 * K))
    return cost, ratio


def _depth_signal(amp, sig, flags):
    """Whether the camera motion determines the depth of the deformation (``amp``:
    :func:`nrsfm.metrics.depth_amplification` of the run's rotations and shapes). Only
    for W with 3K directions: below, W does not determine all of the shapes' modes, and
    the split between camera motion and deformation is not unique (shark: 84,000 on a run
    with e3d .016); the rank signal speaks for those runs."""
    if amp is None:
        return
    sig["depth_amplification"] = amp
    if amp > DEPTH_AMPLIFICATION_MAX and (sig["noise_level"] > DEPTH_NOISE_MIN or
                                          not np.isfinite(amp)):
        flags.append(text("W-depth-undetermined", amp=amp, amp_max=DEPTH_AMPLIFICATION_MAX))


def _rotation_signals(W, K, s, sigma, M_hat, rotation_stage, seed, full_rank, sig, flags,
                      notes):
    """The rotation stage's signals, flags and notes (into ``sig``, ``flags``, ``notes``):
    the triplet's cost against the noise prediction, the search's hits, the filter, the
    depth signs, the cameras' spread, the depth sensitivity and the transpose test."""
    twoF, P = W.shape
    F = twoF // 2
    cost, ratio = _cost_signals(K, s, sigma, M_hat, rotation_stage, seed, sig, flags, notes)
    search = rotation_stage.search
    sig["triplet_hits"], sig["triplet_starts"] = search.hits, search.n_starts
    if search.hits < 2:
        flags.append(text("W-triplet-unconfirmed", hits=search.hits, n_starts=search.n_starts))
    kept = float(np.mean(rotation_stage.kept))
    sig["kept_fraction"] = kept
    if rotation_stage.kept.shape[0] > 1 and kept < KEPT_MIN:
        flags.append(text("W-samples-disagree", kept=kept, kept_min=KEPT_MIN))
    sfrac = float(np.mean(rotation_stage.sign_from_smoothness))
    sig["smoothness_sign_fraction"] = sfrac
    R = rotation_stage.rotations
    d = R[:, 2] * np.where(np.einsum("fi,i->f", R[:, 2], R[0, 2]) < 0, -1.0, 1.0)[:, None]
    mean_d = d.mean(axis=0)
    mean_d /= max(np.linalg.norm(mean_d), 1e-300)
    ang = np.degrees(np.arccos(np.clip(d @ mean_d, -1.0, 1.0)))
    spread = float(np.max(ang))
    sig["camera_spread_deg"] = spread
    if spread < CAMERA_SPREAD_MIN_DEG:
        flags.append(text("W-static-camera", spread=spread, spread_min=CAMERA_SPREAD_MIN_DEG))
    if sfrac > SIGN_FRACTION_MAX:
        # cameras that jump by more than 90 degrees leave the depth sign of a frame to the
        # smoothness rule, which cannot decide it; alone that is the orthographic mirror
        # ambiguity (a random camera per frame: e3d .005),
        # with other flags, or a W of rank below 3K whose triplet does not fit it at the
        # noise level, a sign of wrong rotations (a deforming planar object: Dai's cost
        # 8e5 x its prediction, e3d .73; shark on a random camera, rank 5 < 9 and an exact
        # triplet, e3d 3e-8: the mirror ambiguity alone)
        jumps = dict(n=int(rotation_stage.sign_from_smoothness.sum()), F=F,
                     frac_max=SIGN_FRACTION_MAX)
        wrong = flags or (not full_rank and ratio > COST_RATIO_MAX)
        (flags.append(text("W-camera-jumps", **jumps)) if wrong else
         notes.append(text("N-camera-jumps", **jumps)))
    sig["looks_transposed"] = False
    if ratio > COST_RATIO_MAX and full_rank and P % 2 == 0 and 3 * K <= min(P, twoF - 1):
        Wt = W.T - W.T.mean(axis=1, keepdims=True)
        here = cost / F
        there = _dai_cost_per_frame(Wt, K, seed)
        sig["transposed_cost_per_frame"] = there
        if there < TRANSPOSE_RATIO * here:
            sig["looks_transposed"] = True
            flags.append(text("W-transposed", P=P, twoF=twoF, F_t=P // 2, there=there,
                              here=here))

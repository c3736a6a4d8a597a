"""Quality signals of a reconstruction, each with the threshold that flags it.

``nrsfm.reconstruct`` attaches a :class:`Diagnostics` to every result and issues one
:class:`NRSfMWarning` when a signal crosses its threshold (:data:`THRESHOLDS`). The signals
are measured from W and the run alone, never from ground truth. Every flag and note, its
trigger, meaning and what to do: ``docs/warnings.md`` (:mod:`nrsfm.warnings_catalog`); why
these thresholds: ``docs/studies/rotations.md``.

Signals: ``numerical_rank`` (singular values of the centred W above ``RANK_RTOL s_1``),
``rank_gap`` (``s_3K / s_3K+1``), ``condition`` (``s_1 / s_3K``), ``noise_level``
(:mod:`nrsfm.noise`, relative to W's RMS entry), ``depth_amplification``
(:func:`nrsfm.metrics.depth_amplification`); from the rotation stage: ``triplet_cost_ratio``
(Dai's cost over its noise prediction, :func:`predicted_triplet_cost`), ``triplet_hits``,
``kept_fraction``, ``smoothness_sign_fraction``, ``camera_spread_deg``, ``looks_transposed``;
from the fill of missing data (:func:`diagnose_fill`): ``unreliable_tracks``.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from .stages.completion import MAX_GAIN
from .stages.fill import SPREAD_MAX
from .stages.rotations.subspace import DETERMINED_RTOL, lower_minimum, transposed_cost
from .warnings_catalog import UNRELIABLE, text

#: singular values below ``RANK_RTOL * s_1`` count as zero (the rotation stage's tolerance)
RANK_RTOL = DETERMINED_RTOL
#: smallest acceptable ``s_3K / s_3K+1`` (below: a note)
RANK_GAP_MIN = 1.02
#: largest acceptable ``s_1 / s_3K``
CONDITION_MAX = 1e6
#: largest acceptable ratio of Dai's cost to the cost the noise level predicts
COST_RATIO_MAX = 4.0
#: smallest acceptable fraction of rotation samples kept by the filter
KEPT_MIN = 0.5
#: largest acceptable fraction of frames whose depth sign came from smoothness
SIGN_FRACTION_MAX = 0.10
#: largest acceptable ``depth_amplification`` (1 for cameras from all directions) ...
DEPTH_AMPLIFICATION_MAX = 8.0
#: ... when W has more than rounding beyond its rank-3K part (an exactly rank-3K W with a
#: finite amplification has one exact answer)
DEPTH_NOISE_MIN = 1e-10
#: smallest acceptable largest angle between a viewing direction and their mean (degrees)
CAMERA_SPREAD_MIN_DEG = 10.0
#: floor (per frame) of the predicted triplet cost: keeps the ratio finite on noise-free data
COST_FLOOR_PER_FRAME = 1e-6
#: W "looks transposed" when read as (P, 2F) its best Dai cost per frame is below this
#: fraction of its cost per frame as given
TRANSPOSE_RATIO = 0.25
#: largest acceptable number of unreliable tracks (``Reconstruction.unreliable``: fill gain
#: above ``MAX_GAIN``, fills' spread above ``SPREAD_MAX``) of a run with missing data
UNRELIABLE_TRACKS_MAX = 0
#: the orthographic start's flags about its rotations that a perspective refinement turns
#: into a note: they measure the orthographic model's misfit, and the refinement re-estimates
#: the rotations and each frame's depth order
ORTHOGRAPHIC_START_FLAGS = (
    "W-triplet-bad-minimum",
    "W-triplet-unconfirmed",
    "W-samples-disagree",
    "W-camera-jumps",
    "W-depth-undetermined",
)

THRESHOLDS = dict(
    camera_spread_deg=f"< {CAMERA_SPREAD_MIN_DEG}",
    numerical_rank="< 3K (note unless another flag)",
    rank_gap=f"< {RANK_GAP_MIN} (note)",
    condition=f"> {CONDITION_MAX:g}",
    triplet_cost_ratio=f"> {COST_RATIO_MAX}",
    kept_fraction=f"< {KEPT_MIN}",
    smoothness_sign_fraction=f"> {SIGN_FRACTION_MAX}",
    triplet_hits="< 2",
    looks_transposed="True",
    triplet_unknowns="> 2F (8K - 3 at full rank)",
    depth_amplification=f"> {DEPTH_AMPLIFICATION_MAX} with noise_level > {DEPTH_NOISE_MIN:g}",
    unreliable_tracks=f"> {UNRELIABLE_TRACKS_MAX} (tracks of fill gain > {MAX_GAIN:g} and "
    f"fill spread > {SPREAD_MAX})",
)


class NRSfMWarning(UserWarning):
    """A reconstruction whose quality signals say it is unreliable: the message is
    ``"unreliable reconstruction: "`` and the run's flags, each starting with its id
    (``W-...``, ``docs/warnings.md``), separated by ``"; "``."""


@dataclass
class Diagnostics:
    """Measured quality signals of one run: ``signals`` (name -> value, see the module
    docstring), ``flags`` (one message per signal that crossed its threshold, starting with
    its id ``W-...``: what is wrong, what it means, what to try), ``notes`` (observations
    that need no action, ids ``N-...``) and ``thresholds`` (name -> the rule that flags it).
    """

    signals: dict = field(default_factory=dict)
    flags: list = field(default_factory=list)
    notes: list = field(default_factory=list)
    thresholds: dict = field(default_factory=lambda: dict(THRESHOLDS))

    @property
    def flagged(self):
        return bool(self.flags)

    def summary(self):
        """Lines ``name value (flag rule)`` and the notes and flags, for reports."""
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
    s = np.asarray(singular_values, float)[: M.shape[1]]
    live = s > RANK_RTOL * s[0]  # rows W does not determine carry no noise
    s2 = sigma**2 * np.sum(G[live] ** 2 / s[live, None]) / 3.0
    c2 = 0.5 * np.sum((M @ G).reshape(-1, 2, 3) ** 2, axis=(1, 2))
    c2 = np.maximum(c2, 1e-12 * max(np.median(c2), 1e-300))
    return float(np.sum(16.0 * s2 / c2))


def diagnose(W, K, factorization, rotation_stage=None, seed=0, depth_amplification=None):
    """Measure the quality signals of a run and flag those beyond their thresholds.

    Parameters
    ----------
    W : (2F, P) ndarray
        Row-centred measurements (any scale).
    K : int
    factorization : nrsfm.stages.measurement.Factorization
        The rank-3K factorisation of W (singular values, noise level, M_hat).
    rotation_stage : RotationResult, optional
        None when the rotations were given.
    seed : int
        For the transpose test's triplet search.
    depth_amplification : float, optional
        :func:`nrsfm.metrics.depth_amplification` of the run's rotations and shapes (which
        the diagnostics do not see); None: no depth signal.

    Returns
    -------
    Diagnostics
    """
    W = np.asarray(W, float)
    r = 3 * K
    s = np.asarray(factorization.singular_values, float)
    sig, flags, notes = {}, [], []
    rank = sig["numerical_rank"] = numerical_rank(s)
    full_rank = rank >= r
    nxt = s[r] if s.size > r else 0.0
    gap = sig["rank_gap"] = float(s[r - 1] / nxt) if nxt > 0 else np.inf
    if full_rank and gap < RANK_GAP_MIN:
        notes.append(text("N-no-rank-gap", r=r, gap=gap, gap_min=RANK_GAP_MIN))
    cond = sig["condition"] = float(s[0] / s[r - 1]) if s[r - 1] > 0 else np.inf
    if full_rank and cond > CONDITION_MAX:
        flags.append(text("W-ill-conditioned", cond=cond, cond_max=CONDITION_MAX))
    rms = np.sqrt(np.sum(s**2) / W.size)
    sig["noise_level"] = (
        factorization.noise_level / rms if rms > 0 else 0.0
    )  # relative to W's RMS entry
    amp = depth_amplification
    # below 3K directions the split between camera motion and deformation is not unique:
    # the rank signal speaks for those runs
    if amp is not None and full_rank:
        sig["depth_amplification"] = amp
        undetermined = sig["noise_level"] > DEPTH_NOISE_MIN or not np.isfinite(amp)
        if amp > DEPTH_AMPLIFICATION_MAX and undetermined:
            why = (
                f"the cameras leave it {amp:.3g} x as open as cameras from all directions would"
                if np.isfinite(amp)
                else "no camera sees one of its directions"
            )
            flags.append(text("W-depth-undetermined", why=why, amp_max=DEPTH_AMPLIFICATION_MAX))
    if rotation_stage is not None:
        _rotation_signals(W, K, factorization, rotation_stage, seed, sig, flags, notes)
    if not full_rank:
        # with a confirmed triplet that fits at the noise level not a failure by itself (a
        # note), otherwise a flag and the named cause of the other flags (of the jumps too,
        # if the triplet does not fit: alone they are the mirror ambiguity)
        jumps_only = all(f.startswith("W-camera-jumps") for f in flags)
        fits = sig.get("triplet_cost_ratio", 0.0) <= COST_RATIO_MAX
        if rotation_stage is None or (flags and not (jumps_only and fits)):
            flags.insert(0, text("W-rank-deficient", rank=rank, K=K, r=r, rtol=RANK_RTOL))
        else:
            k_eff = rotation_stage.effective_K
            notes.append(text("N-rank-deficient-subspace", rank=rank, r=r, k_eff=k_eff, K=K))
    return Diagnostics(signals=sig, flags=flags, notes=notes)


def _rotation_signals(W, K, fact, rotation_stage, seed, sig, flags, notes):
    """The rotation stage's signals, flags and notes (into ``sig``, ``flags``, ``notes``)."""
    twoF, P = W.shape
    F = twoF // 2
    full_rank = sig["numerical_rank"] >= 3 * K
    # Dai's constraints give 2 equations per frame on the Gram G G^T of a triplet (rank 3 in
    # r = 3K dimensions: 3r - 3 numbers, up to scale); the k true triplets span a (k - 1)-
    # dimensional family of solutions, so 2F below 3r - k - 3 (8K - 3) leaves it undetermined
    r, k = min(rotation_stage.determined_rank, 3 * K), rotation_stage.effective_K
    need = sig["triplet_unknowns"] = 3 * r - k - 3
    if twoF < need:
        flags.append(text("W-few-frames", F=F, twoF=twoF, need=need, K=K, k_max=(twoF + 3) // 8))
    cost = float(rotation_stage.search.costs[0])
    M_hat = fact.M_hat
    pred = predicted_triplet_cost(
        M_hat, rotation_stage.G[0], fact.singular_values, fact.noise_level
    )
    ratio = cost / max(pred, COST_FLOOR_PER_FRAME * F)
    sig.update(triplet_cost=cost, triplet_cost_predicted=pred, triplet_cost_ratio=ratio)
    if ratio > COST_RATIO_MAX:
        # a failed search when other random starts reach a lower cost, else a model misfit
        lower, other = lower_minimum(M_hat, K, cost, seed)
        sig["triplet_cost_other_starts"] = other
        vals = dict(cost=cost, ratio=ratio, pred=pred)
        if lower:
            flags.append(
                text("W-triplet-bad-minimum", ratio_max=COST_RATIO_MAX, other=other, **vals)
            )
        else:
            notes.append(text("N-model-misfit", r=3 * K, **vals))
    search = rotation_stage.search
    sig["triplet_hits"], sig["triplet_starts"] = search.hits, search.n_starts
    if search.hits < 2:
        flags.append(text("W-triplet-unconfirmed", hits=search.hits, n_starts=search.n_starts))
    kept = sig["kept_fraction"] = float(np.mean(rotation_stage.kept))
    if rotation_stage.kept.shape[0] > 1 and kept < KEPT_MIN:
        flags.append(text("W-samples-disagree", kept=kept, kept_min=KEPT_MIN))
    sfrac = sig["smoothness_sign_fraction"] = float(np.mean(rotation_stage.sign_from_smoothness))
    R = rotation_stage.rotations
    d = R[:, 2] * np.where(np.einsum("fi,i->f", R[:, 2], R[0, 2]) < 0, -1.0, 1.0)[:, None]
    mean_d = d.mean(axis=0)
    mean_d /= max(np.linalg.norm(mean_d), 1e-300)
    spread = float(np.max(np.degrees(np.arccos(np.clip(d @ mean_d, -1.0, 1.0)))))
    sig["camera_spread_deg"] = spread
    if spread < CAMERA_SPREAD_MIN_DEG:
        flags.append(text("W-static-camera", spread=spread, spread_min=CAMERA_SPREAD_MIN_DEG))
    if sfrac > SIGN_FRACTION_MAX:  # each frame's depth sign: W never fixes it (mirror)
        n = int(rotation_stage.sign_from_smoothness.sum())
        flags.append(text("W-camera-jumps", n=n, F=F, frac_max=SIGN_FRACTION_MAX))
    sig["looks_transposed"] = False
    if ratio > COST_RATIO_MAX and full_rank and P % 2 == 0 and 3 * K <= min(P, twoF - 1):
        here = cost / F
        there = transposed_cost(W, K, seed)
        sig["transposed_cost_per_frame"] = there
        if there < TRANSPOSE_RATIO * here:
            sig["looks_transposed"] = True
            flags.append(text("W-transposed", P=P, twoF=twoF, F_t=P // 2, there=there, here=here))


def diagnose_fill(diagnostics, unreliable, by_neighbours=True):
    """Add the fill's signal ``unreliable_tracks`` to a run's ``diagnostics`` (in place), and
    its flag when tracks are unreliable: after the fill, for input with missing data.

    Parameters
    ----------
    diagnostics : Diagnostics
        The run's diagnostics (:func:`diagnose`).
    unreliable : (P,) bool array_like
        ``Reconstruction.unreliable``: tracks seen in too few frames for the data to
        determine their 3D whose fills disagree (or, without the neighbour fill, all of them).
    by_neighbours : bool
        Whether the tracks were filled from their neighbours (``fill="neighbours"``).
    """
    unreliable = np.asarray(unreliable, bool)
    sig, flags = diagnostics.signals, diagnostics.flags
    n = sig["unreliable_tracks"] = int(unreliable.sum())
    if n > UNRELIABLE_TRACKS_MAX:
        why = (
            "their fills from the neighbours disagree"
            if by_neighbours
            else "only the model filled them (fill='model')"
        )
        flags.append(text("W-fills-unreliable", n=n, P=unreliable.size, why=why))


def diagnose_perspective(diagnostics, perspective):
    """Turn a run's ``diagnostics`` (of its orthographic start) into those of its perspective
    refinement (in place): the start's rotation flags (:data:`ORTHOGRAPHIC_START_FLAGS`)
    become one note, and the refinement's own signals ``depth_ratio`` and
    ``perspective_iterations`` are added, flagged beyond their thresholds.

    Parameters
    ----------
    diagnostics : Diagnostics
    perspective : nrsfm.stages.perspective.PerspectiveResult
    """
    from .stages.perspective import MAX_DEPTH_RATIO

    sig, flags, notes = diagnostics.signals, diagnostics.flags, diagnostics.notes
    start = [f for f in flags if f.split(":", 1)[0] in ORTHOGRAPHIC_START_FLAGS]
    flags[:] = [f for f in flags if f not in start]
    if start:
        ids = ", ".join(f.split(":", 1)[0][2:] for f in start)  # no id: one id per message
        notes.append(text("N-orthographic-start", ids=ids))
    ratio = sig["depth_ratio"] = perspective.depth_ratio
    sig["perspective_iterations"] = perspective.n_iter
    if not ratio <= MAX_DEPTH_RATIO:
        flags.append(text("W-perspective-depth", ratio=ratio, ratio_max=MAX_DEPTH_RATIO))
    if not perspective.converged:
        n, tol = perspective.n_iter, perspective.tol
        flags.append(text("W-perspective-not-converged", n=n, tol=tol))

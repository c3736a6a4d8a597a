"""Every warning and note the library issues: id, message and documentation, one table.

Each entry of :data:`CATALOG` is one warning or note: the message the code issues (a
``str.format`` template whose first words are fixed, so that tests and users can match it)
and the documentation of ``docs/warnings.md`` (trigger, meaning, what to do), which
``tools/warnings_doc.py`` writes from this table (``tests/test_warnings_catalog.py`` checks
that the file is up to date and that every warning the code issues has its entry here).

Every message is ``"<id>: <text>"`` (:func:`text`). Ids starting ``W-`` are warnings (the
result may be wrong: act on them), ``N-`` notes (an observation that needs no action: kept
in ``Reconstruction.diagnostics.notes``, the diagnostics summary and the recording, never
issued as a Python warning). The trigger texts name thresholds as ``{NAME}`` fields, filled
with the constants of the modules that own them when the documentation is written.
"""

from __future__ import annotations

from dataclasses import dataclass, field

__all__ = ["CATALOG", "Entry", "UNRELIABLE", "lead", "render_markdown", "text"]

#: the first words of the one :class:`nrsfm.NRSfMWarning` a flagged run issues; the
#: diagnostics' warnings (each starting with its id) follow, separated by "; "
UNRELIABLE = "unreliable reconstruction: "

_DIAG = "`nrsfm/diagnostics.py`"
_FLAG = "`nrsfm.NRSfMWarning` (one per run, with the run's other flags; `result.diagnostics.flags`)"
_NOTE = "note (`result.diagnostics.notes`; no Python warning)"


@dataclass(frozen=True)
class Entry:
    """One warning or note: its message template and its documentation."""

    kind: str          #: "warning" or "note"
    raised: str        #: how it reaches the user
    where: str         #: the code that issues it
    message: str       #: ``str.format`` template of the message after ``"<id>: "``
    trigger: str       #: exact condition; ``{NAME}`` fields are thresholds (render_markdown)
    means: str         #: what it means for the result
    action: str        #: what to do
    example: dict = field(default_factory=dict)   #: values for the documented example


CATALOG = {
    "W-rank-deficient": Entry(
        "warning", _FLAG,
        f"{_DIAG}, `diagnose`",
        "W has only {rank} independent directions where the model with K = {K} needs "
        "3K = {r} (singular values below {rtol:g} s_1 count as zero): part of the model gets "
        "no data, so the cameras and shapes may be wrong; a planar object, a static camera "
        "(rank at most 2K) or a K too large does this; try a lower K (3K <= {rank})",
        "the numerical rank of the centred W (singular values above `RANK_RTOL` = {RANK_RTOL:g}"
        " x s_1) is below 3K, and another diagnostic flags the run too or the rotations were "
        "given; with no other flag and rotations from the rotation stage it is a note instead "
        "(`N-rank-deficient-subspace` when the stage solved in the determined subspace, "
        "`N-rank-deficient` otherwise)",
        "the rank-3K model has directions that W does not contain; the cameras and shapes "
        "along them are not measured. Together with other flags it is their likely cause.",
        "lower K until 3K is at most the rank; check for a planar object or a static camera.",
        dict(rank=4, K=2, r=6, rtol=1e-6)),
    "N-rank-deficient-subspace": Entry(
        "note", _NOTE, f"{_DIAG}, `diagnose`",
        "W has only {rank} independent directions where 3K = {r}; the rotations were solved "
        "in the {rank}-dimensional part that W determines ({k_eff} corrective triplet(s)) "
        "and the shapes use K = {K}; no action needed unless a warning comes with it",
        "numerical rank of W below 3K, no diagnostic flags the run, and the rotation stage "
        "reports `effective_K` (it solved in the determined subspace)",
        "nothing by itself: the rotation stage used only what W determines (shark: rank 5 < "
        "3K = 9, reconstructed at the paper's accuracy this way).",
        "none. If `W-shape-not-unique` comes with it, read that entry.",
        dict(rank=5, r=9, k_eff=1, K=3)),
    "N-no-rank-gap": Entry(
        "note", _NOTE, f"{_DIAG}, `diagnose`",
        "the singular values of W fall smoothly through 3K = {r} (s_3K / s_3K+1 = {gap:.4g},"
        " below {gap_min}): the last of the model's directions are as small as the noise; "
        "no action needed",
        "full numerical rank and `rank_gap` s_3K / s_3K+1 below `RANK_GAP_MIN` = "
        "{RANK_GAP_MIN}",
        "K is not visible in the singular values of W (usual with track noise of 5% or "
        "more); on pickup, drink, yoga and dance with 5-25% noise the rotations stay "
        "accurate.",
        "none; a neighbouring K may fit as well.",
        dict(r=36, gap=1.004, gap_min=1.02)),
    "W-ill-conditioned": Entry(
        "warning", _FLAG, f"{_DIAG}, `diagnose`",
        "the factorisation of W is ill-conditioned: s_1 / s_3K = {cond:.3g} (warned above "
        "{cond_max:g}), so the cameras are computed from directions W barely contains and "
        "may be wrong; try a lower K",
        "full numerical rank and `condition` s_1 / s_3K above `CONDITION_MAX` = "
        "{CONDITION_MAX:g}",
        "the smallest of the 3K directions the model uses is tiny against the largest; "
        "the corrective triplet and the cameras rest on it (MoCap reads 109-16171).",
        "lower K; check that W holds the tracks of one object.",
        dict(cond=3.2e7, cond_max=1e6)),
    "W-triplet-bad-minimum": Entry(
        "warning", _FLAG, f"{_DIAG}, `_cost_signals`",
        "the corrective-triplet search ended in a poor solution: its cost {cost:.3g} is "
        "{ratio:.3g} x what the noise in W explains ({pred:.3g}; warned above {ratio_max}) "
        "and other starts reach {other:.3g}, so the cameras and shapes are likely wrong; try "
        "more starts (RotationSettings max_starts) or another seed",
        "`triplet_cost_ratio` (Dai's cost of the best triplet over the cost the noise level "
        "of W predicts) above `COST_RATIO_MAX` = {COST_RATIO_MAX}, and other random starts "
        "reach a lower cost (`lower_minimum` in `nrsfm/stages/rotations/subspace.py`)",
        "the triplet that turns W's factors into cameras is not the best one: the search "
        "failed, so the rotations and the shapes built on them are unreliable.",
        "rerun with more starts (`RotationSettings(max_starts=...)`, default 40) or "
        "another `seed`; if W may be transposed see `W-transposed`.",
        dict(cost=3.1, ratio=16.0, pred=0.19, ratio_max=4.0, other=0.2)),
    "N-model-misfit": Entry(
        "note", _NOTE, f"{_DIAG}, `_cost_signals`",
        "the corrective triplet's cost {cost:.3g} is {ratio:.3g} x what independent noise on"
        " W predicts ({pred:.3g}) but no other start does better: W is not exactly of rank {r} "
        "(real shapes are not of rank K), the search did not fail; no action needed",
        "`triplet_cost_ratio` above `COST_RATIO_MAX` = {COST_RATIO_MAX} and no other start "
        "reaches a lower cost",
        "W departs from the rank-3K model by more than its noise; the triplet found is the "
        "best there is.",
        "none.",
        dict(cost=0.52, ratio=5.1, pred=0.1, r=36)),
    "W-depth-undetermined": Entry(
        "warning", _FLAG, f"{_DIAG}, `_depth_signal`",
        "the camera motion does not determine the depth of the deformation: the cameras "
        "leave it {amp:.3g} x as open as cameras from all directions would (warned above "
        "{amp_max}), so the prior, not the images, sets the depth of the moving parts, "
        "which may be wrong even where the images fit; a limit of the data, not of the "
        "settings: use views from more varied directions",
        "`depth_amplification` (`nrsfm.metrics.depth_amplification`: the shapes' energy in "
        "the combinations of deformation mode and direction that the cameras see least, "
        "weighted by how little they see them; 1 for cameras from all directions) above "
        "`DEPTH_AMPLIFICATION_MAX` = {DEPTH_AMPLIFICATION_MAX}, W having 3K directions and a "
        "`noise_level` above `DEPTH_NOISE_MIN` = {DEPTH_NOISE_MIN:g} (an exactly rank-3K W "
        "has one exact answer) or the amplification infinite; also with given rotations; "
        "not for the pseudo-inverse shape stage",
        "the deformation moves in directions the cameras hardly see while it moves (e.g. a "
        "camera that turns smoothly through a small angle): measured, e3d above 0.1 even "
        "with the exact rotations on every such run of the validation set.",
        "no setting fixes it; a sequence whose camera (or object) turns more while it "
        "deforms does. Known rotations do not help.",
        dict(amp=38.0, amp_max=8.0)),
    "W-triplet-unconfirmed": Entry(
        "warning", _FLAG, f"{_DIAG}, `_rotation_signals`",
        "only {hits} of {n_starts} starts of the corrective-triplet search reached its best "
        "solution, so it was never confirmed and may be a poor one; try more starts "
        "(RotationSettings max_starts) or another seed",
        "`triplet_hits` (starts that reached the best minimum) below 2",
        "the cameras rest on a minimum found once; it may be a lucky good one or a bad one.",
        "rerun with more starts (`RotationSettings(max_starts=...)`) or another `seed` "
        "and compare.",
        dict(hits=1, n_starts=40)),
    "W-samples-disagree": Entry(
        "warning", _FLAG, f"{_DIAG}, `_rotation_signals`",
        "the K corrective triplets give different rotations: only {kept:.0%} of the "
        "rotation samples agreed enough to be kept (warned below {kept_min:.0%}), so the "
        "averaged cameras rest on few samples and may be wrong; check K",
        "`kept_fraction` (rotation samples that passed the filter) below `KEPT_MIN` = "
        "{KEPT_MIN}, with more than one triplet",
        "the triplets disagree on the cameras; the average is taken over the few that "
        "agree (MoCap keeps 0.56-1.0).",
        "check K (a K too large gives triplets with no data); look at the rotation samples "
        "in the recording (`--rrd`).",
        dict(kept=0.21, kept_min=0.5)),
    "W-camera-jumps": Entry(
        "warning", _FLAG, f"{_DIAG}, `_rotation_signals`",
        "the estimated cameras jump between frames: {n} of {F} frames had their depth sign "
        "set by motion smoothness (warned above {frac_max:.0%}), and the run has other "
        "warnings or W has fewer than 3K directions with a triplet that does not fit it: "
        "together a sign of wrong rotations; check that the frames are in time order",
        "`smoothness_sign_fraction` (frames whose depth sign the motion-smoothness rule "
        "changed) above `SIGN_FRACTION_MAX` = {SIGN_FRACTION_MAX}, and another diagnostic "
        "flags the run, or the numerical rank of W is below 3K and Dai's cost of the best "
        "triplet is above `COST_RATIO_MAX` = {COST_RATIO_MAX} x its noise prediction; "
        "otherwise it is the note `N-camera-jumps`",
        "consecutive cameras differ by more than 90 degrees in many frames while other "
        "signals say the rotations are unreliable (a deforming planar object, rank 2K: e3d "
        ".73): the rotations are likely wrong, or the frames are not in time order.",
        "put the frames in time order; if they are, treat the rotations as failed (see the "
        "run's other warnings).",
        dict(n=30, F=80, frac_max=0.1)),
    "N-camera-jumps": Entry(
        "note", _NOTE, f"{_DIAG}, `_rotation_signals`",
        "the cameras turn by more than 90 degrees between consecutive frames ({n} of {F} "
        "frames had their depth sign set by motion smoothness): an orthographic camera does "
        "not tell a shape from its mirror image in depth, so each of these frames may show "
        "the mirror image; nothing else in the run looks wrong; no action needed if the "
        "camera does jump",
        "`smoothness_sign_fraction` above `SIGN_FRACTION_MAX` = {SIGN_FRACTION_MAX}, no "
        "other diagnostic flags the run, and W has 3K directions or its best triplet fits "
        "it at the noise level (shark on a random camera: rank 5 < 9, e3d 3e-8)",
        "the cameras and shapes are right up to the depth sign of each frame (a random camera"
        " per frame on re-projected MoCap: e3d .005-.03, which measures up to a reflection), "
        "and e_R counts the mirrored frames as errors.",
        "none if the views are unrelated (photos, a shuffled sequence); if the frames are a "
        "video in time order, the camera should not jump: check the tracks.",
        dict(n=30, F=80, frac_max=0.1)),
    "W-static-camera": Entry(
        "warning", _FLAG, f"{_DIAG}, `_rotation_signals`",
        "the camera hardly turns: the estimated viewing directions stay within {spread:.2g} "
        "degrees of their mean (warned below {spread_min} degrees), so the images carry "
        "almost no depth and the 3D shapes are guesses; use a sequence in which the camera "
        "or the object turns more",
        "`camera_spread_deg` (largest angle between a frame's estimated viewing direction "
        "and their mean) below `CAMERA_SPREAD_MIN_DEG` = {CAMERA_SPREAD_MIN_DEG}",
        "a (nearly) static camera observes no depth: the shapes' depth is not measured.",
        "use data with more viewpoint change; no setting fixes it.",
        dict(spread=0.8, spread_min=10.0)),
    "W-transposed": Entry(
        "warning", _FLAG, f"{_DIAG}, `_rotation_signals`",
        "W looks transposed: read as ({P}, {twoF}) = ({F_t} frames, {twoF} points) it fits "
        "orthographic cameras far better (Dai's cost per frame {there:.3g} against "
        "{here:.3g}), so this result is meaningless; pass W.T if W is (P, 2F)",
        "`triplet_cost_ratio` above `COST_RATIO_MAX` = {COST_RATIO_MAX}, W of full rank "
        "with an even number of columns and 3K <= min(P, 2F - 1), and W' read as "
        "measurements reaches a Dai cost per "
        "frame below `TRANSPOSE_RATIO` = {TRANSPOSE_RATIO} x that of W",
        "frames and points are probably swapped; nothing computed from this W is a "
        "reconstruction.",
        "pass `W.T` (W must be (2F, P): rows x and y of each frame, columns points).",
        dict(P=30, twoF=120, F_t=15, there=0.0, here=0.28)),
    "W-shape-not-unique": Entry(
        "warning", "`RuntimeWarning` (CLI: a `nrsfm: warning:` line)",
        "`nrsfm/stages/shape/bilinear.py`, `_balance_mu`",
        "W and these cameras do not determine the shapes on their own (closed-form nullspace "
        "gap {gap:.1e}): many rank-{K} shapes fit W equally well and the prior picks one, its "
        "weight raised to min_mu = {min_mu:g} ||W||_F; if the diagnostics warn too, try a "
        "lower K",
        "the bilinear shape solver with `mu` unset (the default), at rank K: the closed "
        "form's (K+1)-th eigenvalue relative to "
        "its largest is at most `NULLSPACE_GAP_MIN` = {NULLSPACE_GAP_MIN:g}. The closed form "
        "works in W's column space (at most 3K directions), so a W of rank below 3K alone "
        "does not trigger it (shark, rank 5 < 3K = 9: gap 4.5e-5)",
        "the data leave a family of shapes; the one returned is chosen by the prior (mu at "
        "least `min_mu` ||W||_F, default 1e-5).",
        "none if the diagnostics report no warning (the default run on shark gives this); "
        "otherwise lower K. To change the pick set `BilinearSettings(min_mu=...)`.",
        dict(gap=7.6e-33, K=3, min_mu=1e-5)),
    "W-shape-not-unique-mu-given": Entry(
        "warning", "`RuntimeWarning` (CLI: a `nrsfm: warning:` line)",
        "`nrsfm/stages/shape/bilinear.py`, `_balance_mu`",
        "W and these cameras do not determine the shapes on their own (closed-form nullspace "
        "gap {gap:.1e}): many rank-{K} shapes fit W equally well and the result is the one the "
        "given mu = {mu:g} picks, an arbitrary one if mu = 0; leave mu unset to let the "
        "prior choose, or lower K",
        "as `W-shape-not-unique`, with `mu` given (`BilinearSettings(mu=...)`)",
        "the returned shape is one member of a family that fits W equally well; with mu = 0 "
        "rounding picks it.",
        "leave `mu` unset (the default raises it to `min_mu`), use the `admm` solver, or "
        "lower K.",
        dict(gap=7.6e-33, K=3, mu=0.0)),
    "W-completion-cap": Entry(
        "warning", "`RuntimeWarning` (CLI: a `nrsfm: warning:` line)",
        "`nrsfm/stages/completion/__init__.py`, `complete`",
        "the filling of W's missing entries stopped at its iteration cap ({n_iter}) before "
        "converging: the filled entries may be off, usually slightly; the tracks seen in "
        "few frames (result.undetermined) are the least reliable",
        "the completion (`soft_impute`: 500 iterations, `factorisation`: 300) reached its "
        "iteration cap with its change still above tolerance (`Completion.converged` False)",
        "the filled entries are not at the completion's optimum. Measured on MoCap at 30% "
        "missing: e3d capped / uncapped 0.1105 / 0.1098 (pickup), 0.0341 / 0.0319 (drink) "
        "(`docs/studies/missing_data.md`): usually a small loss.",
        "compare with the complete tracks only (`nrsfm video --complete-tracks`, or the "
        "columns of W without NaN); the other completion "
        "(`settings.measurement.completion`) may converge.",
        dict(n_iter=500)),
    "W-ignored-arrays": Entry(
        "warning", "`UserWarning`, printed by the CLI as a `nrsfm: warning:` line",
        "`nrsfm/cli/run.py`, `_read_input`",
        "nrsfm run ignores arrays of {inp} that it does not read: {ignored} (it reads "
        "{keys}); rename one if it was meant as input",
        "`nrsfm run` on an .npz with arrays other than `INPUT_KEYS` = {INPUT_KEYS}",
        "those arrays played no part in the result.",
        "none if they are extra data; rename an array that was meant as W, K, shapes, "
        "rotations or edges.",
        dict(inp="seq.npz", ignored=["colour"], keys="W, K, shapes, rotations, edges")),
}


def text(wid, **values):
    """The message of warning or note ``wid``: ``"<id>: "`` and its filled template."""
    return f"{wid}: " + CATALOG[wid].message.format(**values)


def lead(wid):
    """The fixed first words of ``wid``'s message (up to its first value)."""
    return f"{wid}: " + CATALOG[wid].message.split("{", 1)[0].rstrip(" (")


def _section(wid, entry, constants):
    kind = "warning" if entry.kind == "warning" else "note: no action needed"
    return [f"## {wid}", "",
            f"- **Kind:** {kind}; issued as {entry.raised}.",
            f"- **Where:** {entry.where}.",
            f"- **Message starts with:** `{lead(wid)}`",
            f"- **Example:** {text(wid, **entry.example)}",
            f"- **Trigger:** {entry.trigger.format(**constants)}.",
            f"- **What it means:** {entry.means}",
            f"- **What to do:** {entry.action}", ""]


def render_markdown(constants):
    """``docs/warnings.md``: the catalog, thresholds filled from ``constants``."""
    lines = ["# Warnings and notes", "",
             "Every warning the library can issue, and the notes it records instead of "
             "warning. Written from `nrsfm/warnings_catalog.py` by `python "
             "tools/warnings_doc.py`; edit the catalog, not this file.", "",
             "Every message starts with its id. Ids `W-...` are warnings: the result may be "
             "wrong, and the entry says what to try. Ids `N-...` are notes: observations "
             "that need no action, kept in `result.diagnostics.notes`, in the diagnostics "
             "summary (`result.diagnostics.summary()`, the recording's report) and printed "
             "by the CLI as `note:` lines; they are never Python warnings.", "",
             "The diagnostics' warnings of one run come as one `nrsfm.NRSfMWarning` whose "
             f"message is `{UNRELIABLE.strip()}` followed by each warning's message, "
             "separated by `; ` (`result.diagnostics.flags` holds them one by one; the CLI "
             "prints each as a `WARNING:` line of its report). Other warnings are "
             "`RuntimeWarning` or `UserWarning`; the CLI prints each as one line "
             "`nrsfm: warning: <message>` on stderr.", "",
             "| id | kind | issued as |", "|---|---|---|"]
    lines += [f"| [{wid}](#{wid.lower()}) | {e.kind} | {e.raised.split(' (')[0]} |"
              for wid, e in CATALOG.items()]
    lines.append("")
    for wid, entry in CATALOG.items():
        lines += _section(wid, entry, constants)
    return "\n".join(lines)

"""Every warning and note the library issues: id, message and documentation, one table.

Each entry of :data:`CATALOG` is the message the code issues (a ``str.format`` template
whose first words are fixed, so that tests and users can match it) and the documentation
``tools/warnings_doc.py`` writes to ``docs/warnings.md``. Every message is ``"<id>: <text>"``
(:func:`text`): ``W-`` warnings (the result may be wrong), ``N-`` notes (no action needed,
never a Python warning). ``{NAME}`` fields of the triggers are the owning modules' constants.
"""

from __future__ import annotations

import re
from dataclasses import dataclass

#: the first words of the one :class:`nrsfm.NRSfMWarning` a flagged run issues; the
#: diagnostics' warnings (each starting with its id) follow, separated by "; "
UNRELIABLE = "unreliable reconstruction: "

_FLAG = "`nrsfm.NRSfMWarning` (one per run, with the run's other flags; `result.diagnostics.flags`)"
_NOTE = "note (`result.diagnostics.notes`; no Python warning)"
_RUNTIME = "`RuntimeWarning` (CLI: a `nrsfm: warning:` line)"


@dataclass(frozen=True)
class Entry:
    """One warning or note: its message template and its documentation."""

    message: str  #: ``str.format`` template of the message after ``"<id>: "``
    trigger: str  #: exact condition; ``{NAME}`` fields are thresholds (render_markdown)
    means: str  #: what it means for the result
    action: str  #: what to do
    example: dict  #: values for the documented example
    raised: str = None  #: how it reaches the user (default: a diagnostics flag or note)
    where: str = "`nrsfm/diagnostics.py`"  #: the code that issues it


CATALOG = {
    "W-rank-deficient": Entry(
        "W has only {rank} independent directions where the model with K = {K} needs 3K = {r} "
        "(singular values below {rtol:g} s_1 count as zero): part of the model gets no data, so "
        "the cameras and shapes may be wrong; a planar object, a static camera (rank at most 2K) "
        "or a K too large does this; try a lower K (3K <= {rank})",
        "the numerical rank of the centred W (singular values above `RANK_RTOL` = {RANK_RTOL:g} x "
        "s_1) below 3K, with given rotations or another flag (`W-camera-jumps` only with a cost "
        "ratio above `COST_RATIO_MAX` = {COST_RATIO_MAX}; else `N-rank-deficient-subspace`)",
        "the cameras and shapes along the model's directions that W lacks are not measured.",
        "lower K until 3K is at most the rank; check for a planar object or a static camera.",
        dict(rank=4, K=2, r=6, rtol=1e-6),
    ),
    "N-rank-deficient-subspace": Entry(
        "W has only {rank} independent directions where 3K = {r}; the rotations were solved in "
        "the {rank}-dimensional part that W determines ({k_eff} corrective triplet(s)) and the "
        "shapes use K = {K}; no action needed unless a warning comes with it",
        "numerical rank of W below 3K, no diagnostic flags the run, and the rotation stage solved "
        "in the determined subspace (`effective_K`)",
        "nothing by itself: the rotation stage used only what W determines.",
        "none. If `W-shape-not-unique` comes with it, read that entry.",
        dict(rank=5, r=9, k_eff=1, K=3),
    ),
    "N-no-rank-gap": Entry(
        "the singular values of W fall smoothly through 3K = {r} (s_3K / s_3K+1 = {gap:.4g}, "
        "below {gap_min}): the last of the model's directions are as small as the noise; no "
        "action needed",
        "full numerical rank and `rank_gap` s_3K / s_3K+1 below `RANK_GAP_MIN` = {RANK_GAP_MIN}",
        "K is not visible in the singular values of W (usual with 5% track noise or more).",
        "none; a neighbouring K may fit as well.",
        dict(r=36, gap=1.004, gap_min=1.02),
    ),
    "W-ill-conditioned": Entry(
        "the factorisation of W is ill-conditioned: s_1 / s_3K = {cond:.3g} (warned above "
        "{cond_max:g}), so the cameras are computed from directions W barely contains and may be "
        "wrong; try a lower K",
        "full numerical rank and `condition` s_1 / s_3K above `CONDITION_MAX` = {CONDITION_MAX:g}",
        "the cameras rest on a direction of W that is tiny against the largest.",
        "lower K; check that W holds the tracks of one object.",
        dict(cond=3.2e7, cond_max=1e6),
    ),
    "W-triplet-bad-minimum": Entry(
        "the corrective-triplet search ended in a poor solution: its cost {cost:.3g} is "
        "{ratio:.3g} x what the noise in W explains ({pred:.3g}; warned above {ratio_max}) and "
        "other starts reach {other:.3g}, so the cameras and shapes are likely wrong; try more "
        "starts (RotationSettings max_starts) or another seed",
        "`triplet_cost_ratio` (Dai's cost of the best triplet over its noise prediction) above "
        "`COST_RATIO_MAX` = {COST_RATIO_MAX}, and other random starts reach a lower cost",
        "the search for the corrective triplet failed: the rotations and shapes are unreliable.",
        "rerun with more starts (`RotationSettings(max_starts=...)`) or another `seed`.",
        dict(cost=3.1, ratio=16.0, pred=0.19, ratio_max=4.0, other=0.2),
    ),
    "N-model-misfit": Entry(
        "the corrective triplet's cost {cost:.3g} is {ratio:.3g} x what independent noise on W "
        "predicts ({pred:.3g}) but no other start does better: W is not exactly of rank {r} (real "
        "shapes are not of rank K), the search did not fail; no action needed",
        "`triplet_cost_ratio` above `COST_RATIO_MAX` = {COST_RATIO_MAX} and no other start "
        "reaches a lower cost",
        "W departs from the rank-3K model by more than its noise; the triplet is the best there "
        "is.",
        "none.",
        dict(cost=0.52, ratio=5.1, pred=0.1, r=36),
    ),
    "W-depth-undetermined": Entry(
        "the camera motion does not determine the depth of the deformation: {why} (warned "
        "above {amp_max}), so "
        "the prior, not the images, sets the depth of the moving parts, which may be wrong even "
        "where the images fit; a limit of the data, not of the settings: use views from more "
        "varied directions",
        "`depth_amplification` (`nrsfm.metrics`) above `DEPTH_AMPLIFICATION_MAX` = "
        "{DEPTH_AMPLIFICATION_MAX}, W of 3K directions with `noise_level` above `DEPTH_NOISE_MIN` "
        "= {DEPTH_NOISE_MIN:g} or the amplification infinite (given rotations too; not for the "
        "pseudo-inverse)",
        "the deformation moves in directions the cameras hardly see while it moves.",
        "no setting fixes it; a sequence whose camera or object turns more while it deforms does.",
        dict(
            why="the cameras leave it 38 x as open as cameras from all directions would",
            amp_max=8.0,
        ),
    ),
    "W-few-frames": Entry(
        "too few frames for K = {K}: the {F} frames give 2F = {twoF} equations on the corrective "
        "triplet, which needs {need} (8K - 3 at full rank), so W does not determine the rotations "
        "and they may be wrong; use K <= {k_max} or more frames",
        "`triplet_unknowns` (3r - k - 3 for W's rank r <= 3K and k triplets) above 2F",
        "Dai's orthonormality constraints leave the triplet, hence the cameras, undetermined.",
        "lower K to at most (2F + 3) / 8, or add frames.",
        dict(F=17, twoF=34, need=45, K=6, k_max=4),
    ),
    "W-triplet-unconfirmed": Entry(
        "only {hits} of {n_starts} starts of the corrective-triplet search reached its best "
        "solution, so it was never confirmed and may be a poor one; try more starts "
        "(RotationSettings max_starts) or another seed",
        "`triplet_hits` (starts that reached the best minimum) below 2",
        "the cameras rest on a minimum found once; it may be a lucky good one or a bad one.",
        "rerun with more starts (`RotationSettings(max_starts=...)`) or another `seed`.",
        dict(hits=1, n_starts=40),
    ),
    "W-samples-disagree": Entry(
        "the K corrective triplets give different rotations: only {kept:.0%} of the rotation "
        "samples agreed enough to be kept (warned below {kept_min:.0%}), so the averaged cameras "
        "rest on few samples and may be wrong; check K",
        "`kept_fraction` (rotation samples that passed the filter) below `KEPT_MIN` = {KEPT_MIN}, "
        "with more than one triplet",
        "the triplets disagree on the cameras; the average is taken over the few that agree.",
        "check K (a K too large gives triplets with no data).",
        dict(kept=0.21, kept_min=0.5),
    ),
    "W-camera-jumps": Entry(
        "the cameras jump: {n} of {F} frames had their depth sign set by motion smoothness "
        "(warned above {frac_max:.0%}), as if the camera turned by more than 90 degrees between "
        "frames; an orthographic camera does not tell a shape from its mirror image in depth, so "
        "W does not determine these frames' rotations and each may be the mirror image; for a "
        "video, check that the frames are in time order; for unrelated views, take each frame's "
        "depth as unknown",
        "`smoothness_sign_fraction` above `SIGN_FRACTION_MAX` = {SIGN_FRACTION_MAX}",
        "rotations and camera-frame shapes are right at best up to each frame's depth sign "
        "(e_R counts mirrored frames; e3d aligns each frame and does not).",
        "put the frames in time order; for unrelated views no setting decides the depth signs.",
        dict(n=30, F=80, frac_max=0.1),
    ),
    "W-static-camera": Entry(
        "the camera hardly turns: the estimated viewing directions stay within {spread:.2g} "
        "degrees of their mean (warned below {spread_min} degrees), so the images carry almost no "
        "depth and the 3D shapes are guesses; use a sequence in which the camera or the object "
        "turns more",
        "`camera_spread_deg` below `CAMERA_SPREAD_MIN_DEG` = {CAMERA_SPREAD_MIN_DEG}",
        "a (nearly) static camera observes no depth: the shapes' depth is not measured.",
        "use data with more viewpoint change; no setting fixes it.",
        dict(spread=0.8, spread_min=10.0),
    ),
    "W-transposed": Entry(
        "W looks transposed: read as ({P}, {twoF}) = ({F_t} frames, {twoF} points) it fits "
        "orthographic cameras far better (Dai's cost per frame {there:.3g} against {here:.3g}), "
        "so this result is meaningless; pass W.T if W is (P, 2F)",
        "cost ratio above `COST_RATIO_MAX` = {COST_RATIO_MAX}, W' read as measurements (P even) "
        "reaching a Dai cost per frame below `TRANSPOSE_RATIO` = {TRANSPOSE_RATIO} x W's",
        "frames and points are probably swapped.",
        "pass `W.T` (W must be (2F, P): rows x and y of each frame, columns points).",
        dict(P=30, twoF=120, F_t=15, there=0.0, here=0.28),
    ),
    "W-shape-not-unique": Entry(
        "W and these cameras do not determine the shapes on their own (closed-form nullspace gap "
        "{gap:.1e}): many rank-{K} shapes fit W equally well and the prior picks one, its weight "
        "raised to min_mu = {min_mu:g} ||W||_F; if the diagnostics warn too, try a lower K",
        "the bilinear shape solver with `mu` unset: the closed form's (K+1)-th eigenvalue "
        "relative to its largest is at most `NULLSPACE_GAP_MIN` = {NULLSPACE_GAP_MIN:g}",
        "the data leave a family of shapes; the prior chooses the one returned.",
        "none if the diagnostics report no warning; else lower K (or "
        "`BilinearSettings(min_mu=...)`).",
        dict(gap=7.6e-33, K=3, min_mu=1e-5),
        raised=_RUNTIME,
        where="`nrsfm/stages/shape/bilinear.py`",
    ),
    "W-shape-not-unique-mu-given": Entry(
        "W and these cameras do not determine the shapes on their own (closed-form nullspace gap "
        "{gap:.1e}): many rank-{K} shapes fit W equally well and the result is the one the given "
        "mu = {mu:g} picks, an arbitrary one if mu = 0; leave mu unset to let the prior choose, "
        "or lower K",
        "as `W-shape-not-unique`, with `mu` given (`BilinearSettings(mu=...)`)",
        "the shape returned is one of a family that fits W equally well.",
        "leave `mu` unset (the default raises it to `min_mu`), use the `admm` solver, or lower K.",
        dict(gap=7.6e-33, K=3, mu=0.0),
        raised=_RUNTIME,
        where="`nrsfm/stages/shape/bilinear.py`",
    ),
    "W-completion-cap": Entry(
        "the filling of W's missing entries stopped at its iteration cap ({n_iter}) before "
        "converging: the filled entries may be off, usually slightly; the tracks seen in few "
        "frames (result.undetermined) are the least reliable",
        "the completion reached its iteration cap (`Completion.converged` False)",
        "the filled entries are not at the completion's optimum: usually a small loss.",
        "compare with the complete tracks only, or the other `MeasurementSettings.completion`.",
        dict(n_iter=500),
        raised=_RUNTIME,
        where="`nrsfm/stages/completion/__init__.py`",
    ),
    "W-fills-unreliable": Entry(
        "tracks seen too rarely: {n} of {P} tracks were seen in too few frames for the data to "
        "determine their 3D and {why}, so their 3D in the frames they were not seen is an "
        "extrapolation that may be far off; add frames in which they are seen, drop them, or "
        "mask them with result.unreliable",
        "`unreliable_tracks`, the number of tracks in `Reconstruction.unreliable`, above "
        "`UNRELIABLE_TRACKS_MAX` = {UNRELIABLE_TRACKS_MAX}: input with missing entries, tracks "
        "whose fill gain is above `MAX_GAIN` = {MAX_GAIN:g} and, with the neighbour fill, whose "
        "four fills stray from their median by more than `SPREAD_MAX` = {SPREAD_MAX} of the "
        "shapes' RMS radius (`fill_spread`)",
        "the 3D of those tracks in the frames they were not seen is a guess from their "
        "neighbours and the model, not a measurement, and may be far off; the flag is about "
        "those tracks only.",
        "record more frames in which those tracks are seen, drop them from W, or leave them out "
        "where the shapes are used (`result.shapes[:, :, ~result.unreliable]`).",
        dict(n=15, P=992, why="their fills from the neighbours disagree"),
    ),
    "N-orthographic-start": Entry(
        "the orthographic start raised the flags {ids}: a pinhole camera's tracks do not fit the "
        "orthographic model exactly, and the perspective refinement re-estimates the rotations "
        "and each frame's depth order from that start; no action needed unless a warning comes "
        "with it",
        "`reconstruct(..., intrinsics=)` and the orthographic start raised one of "
        "`ORTHOGRAPHIC_START_FLAGS` = {ORTHOGRAPHIC_START_FLAGS}",
        "the orthographic rotation stage measured the misfit of its camera model; the answer is "
        "the perspective fit's.",
        "none; read the perspective warnings if any.",
        dict(ids="camera-jumps"),
        where="`nrsfm/diagnostics.py` (`diagnose_perspective`)",
    ),
    "W-perspective-depth": Entry(
        "the perspective fit puts one point {ratio:.3g} times as deep as another in one frame "
        "(warned above {ratio_max:g}, a camera within 11/9 of the object's radius): the images "
        "do not determine the depth and every start left it; check the intrinsics (the focal "
        "length in pixels, the principal point) or use a lower K",
        "`depth_ratio` of the perspective answer above `MAX_DEPTH_RATIO` = {MAX_DEPTH_RATIO:g} "
        "(`nrsfm.stages.perspective`)",
        "points were pushed towards the camera's centre and away: the shapes' depth is not "
        "measured.",
        "check the intrinsics; lower K; use frames with more camera motion.",
        dict(ratio=47.2, ratio_max=10),
        where="`nrsfm/diagnostics.py` (`diagnose_perspective`)",
    ),
    "W-perspective-not-converged": Entry(
        "the perspective refinement stopped after its {n} iterations "
        "(PerspectiveSettings max_iter) while E still fell by more than tol = {tol:g} of itself: "
        "the answer depends on where it stopped; raise max_iter",
        "the chosen start's fit reached `PerspectiveSettings.max_iter` iterations",
        "the shapes and cameras are not a minimum of the refinement's objective.",
        "raise `PerspectiveSettings(max_iter=...)`.",
        dict(n=200, tol=1e-6),
        where="`nrsfm/diagnostics.py` (`diagnose_perspective`)",
    ),
    "W-ignored-arrays": Entry(
        "nrsfm run ignores arrays of {inp} that it does not read: {ignored} (it reads {keys}); "
        "rename one if it was meant as input",
        "`nrsfm run` on an .npz with arrays other than `INPUT_KEYS` = {INPUT_KEYS}",
        "those arrays played no part in the result.",
        "none if they are extra data; else rename them.",
        dict(inp="seq.npz", ignored=["colour"], keys="W, K, shapes, rotations, edges"),
        raised="`UserWarning`, printed by the CLI as a `nrsfm: warning:` line",
        where="`nrsfm/cli/run.py`",
    ),
}


def text(wid, **values):
    """The message of warning or note ``wid``: ``"<id>: "`` and its filled template."""
    return f"{wid}: " + CATALOG[wid].message.format(**values)


def ids_in(message):
    """The catalog ids a warning's message names, in order: one for most warnings, every
    flag of the run for an ``NRSfMWarning`` (its flags joined by ``"; "``)."""
    return [w for w in re.findall(r"\b([WN]-[a-z]+(?:-[a-z]+)*): ", str(message)) if w in CATALOG]


def lead(wid):
    """The fixed first words of ``wid``'s message (up to its first value)."""
    return f"{wid}: " + CATALOG[wid].message.split("{", 1)[0].rstrip(" (")


def kind(wid):
    """``"warning"`` or ``"note"``, from the id."""
    return "note" if wid.startswith("N-") else "warning"


def raised(wid):
    """How warning or note ``wid`` reaches the user."""
    return CATALOG[wid].raised or (_NOTE if kind(wid) == "note" else _FLAG)


def _section(wid, entry, constants):
    how = "warning" if kind(wid) == "warning" else "note: no action needed"
    return [
        f"## {wid}",
        "",
        f"- **Kind:** {how}; issued as {raised(wid)}.",
        f"- **Where:** {entry.where}.",
        f"- **Message starts with:** `{lead(wid)}`",
        f"- **Example:** {text(wid, **entry.example)}",
        f"- **Trigger:** {entry.trigger.format(**constants)}.",
        f"- **What it means:** {entry.means}",
        f"- **What to do:** {entry.action}",
        "",
    ]


_INTRO = f"""# Warnings and notes

Every warning the library can issue, and the notes it records instead of warning. Written
from `nrsfm/warnings_catalog.py` by `python tools/warnings_doc.py`; edit the catalog, not
this file.

Every message starts with its id. Ids `W-...` are warnings: the result may be wrong, and the
entry says what to try. Ids `N-...` are notes: observations that need no action, kept in
`result.diagnostics.notes`, in the diagnostics summary (`result.diagnostics.summary()`, the
recording's report); the summary the CLI prints names them by id on one `notes` line. They
are never Python warnings.

The diagnostics' warnings of one run come as one `nrsfm.NRSfMWarning` whose message is
`{UNRELIABLE.strip()}` followed by each warning's message, separated by `; `
(`result.diagnostics.flags` holds them one by one; the CLI prints each as a `WARNING:` line
of its report). Other warnings are `RuntimeWarning` or `UserWarning`; the CLI prints each as
one line `nrsfm: warning: <message>` on stderr.

| id | kind | issued as |
|---|---|---|
"""


def render_markdown(constants):
    """``docs/warnings.md``: the catalog, thresholds filled from ``constants``."""
    lines = [_INTRO.rstrip("\n")]
    lines += [f"| [{w}](#{w.lower()}) | {kind(w)} | {raised(w).split(' (')[0]} |" for w in CATALOG]
    lines.append("")
    for wid, entry in CATALOG.items():
        lines += _section(wid, entry, constants)
    return "\n".join(lines)

"""The lost-tracks table of the ``missing`` experiment (issue 24): where the loss of a
reconstruction with missing data is, and how well its fills and its flag are.

One task per sequence and pattern (:func:`missing_track_tasks`; the runner is
:func:`nrsfm.experiments.tasks.run_missing_tracks`): the organic pipeline on the complete
W and on W with a fraction of the tracks hit by one of the patterns of
:func:`data_tools.drop_tracks` (issue 24's: ``lost``, 0.3 of the tracks, seed 31). Its row
(:func:`track_row`) holds

* e3d with complete and with missing data, and e3d over the points seen in each frame for
  both (:func:`nrsfm.experiments.fill.e3d_seen`);
* the lost points (missing in at least one frame), those flagged unreliable
  (:attr:`nrsfm.Reconstruction.unreliable`: undetermined, and where filled from their
  neighbours, with neighbour fills that disagree);
* each lost point's fill error: the mean over the frames it was not seen in of its 3D
  error after e3d's per-frame similarity alignment, RMS shape radius = 1
  (:func:`nrsfm.experiments.fill.point_errors`), for the pipeline's fill and for the
  rigid-neighbour baseline (:func:`nrsfm.experiments.fill.rigid_neighbour_fill` on the
  pipeline's shapes of the seen points, aligned the same way).
"""

from __future__ import annotations

import numpy as np

from .fill import e3d_seen, lost_point_means, point_errors, rigid_neighbour_fill

__all__ = ["COLUMNS", "TITLE", "missing_track_table", "missing_track_tasks", "track_row"]

TITLE = "Lost tracks: where the error is, the fills and their flag (issue 24)"

#: the table's columns (:func:`missing_track_table`)
COLUMNS = ["sequence", "pattern", "missing", "e3d complete", "e3d missing", "ratio",
           "e3d seen, complete", "e3d seen, missing", "lost points", "flagged",
           "fill flagged", "range", "fill unflagged", "range", "fill lost",
           "fill rigid-neighbour", "range",
           "fill > .15 unflagged", "fill < .05 flagged", "s total"]

_FILL_BAD, _FILL_GOOD = 0.15, 0.05          # issue 24's acceptance 2


def missing_track_tasks(make, sequences, patterns, fraction, drop_seed):
    """``make("missing_tracks", ...)`` for every sequence and pattern.

    Parameters
    ----------
    make : callable
        The plan's task maker (``make(experiment, **params)``).
    sequences, patterns : sequence of str
        Patterns: some of :data:`data_tools.noise.PATTERNS`.
    fraction : float
    drop_seed : int
        Seed of the missing-data draw (issue 24: 31).
    """
    from data_tools.noise import PATTERNS

    from ..validation import check_choice

    return [make("missing_tracks", sequence=n,
                 pattern=check_choice("missing pattern", pt, PATTERNS),
                 fraction=float(fraction), drop_seed=int(drop_seed))
            for n in sequences for pt in patterns]


def _mean(values):
    return float(np.mean(values)) if len(values) else None


def _range(values):
    """``"min-max"`` of some fill errors (two decimals), None for none."""
    return f"{min(values):.2f}-{max(values):.2f}" if len(values) else None


def _ranges(row):
    """The fill ranges of a row: flagged, unflagged, rigid-neighbour."""
    flagged = set(row["flagged"])
    fills = list(zip(row["lost"], row["point_fill"]))
    return (_range([x for p, x in fills if p in flagged]),
            _range([x for p, x in fills if p not in flagged]),
            _range(row["point_fill_rigid"]))


def track_row(complete, missing, truth, observed):
    """The metrics of one sequence and pattern (a dict of JSON values).

    Parameters
    ----------
    complete, missing : nrsfm.Reconstruction
        The pipeline on the complete W and on W with the missing entries.
    truth : (F, 3, P) ndarray
        Ground-truth shapes.
    observed : (F, P) bool ndarray
        True where a point was seen.

    Returns
    -------
    dict
        ``e3d_seen_complete``, ``e3d_seen_missing``, ``lost`` (the lost points),
        ``flagged`` (those of them unreliable), ``point_fill`` and ``point_fill_rigid``
        (their mean fill errors, pipeline and baseline, in the order of ``lost``), and the
        means ``fill_flagged``, ``fill_unflagged``, ``fill_lost``, ``fill_rigid`` (None
        where no point is of the kind).
    """
    lost = np.flatnonzero(~observed.all(axis=0))
    flagged = missing.unreliable[lost]
    fill = lost_point_means(point_errors(missing.shapes, truth), observed)[lost]
    rigid = rigid_neighbour_fill(missing.shapes, observed)
    fill_rigid = lost_point_means(point_errors(rigid, truth), observed)[lost]
    return dict(e3d_seen_complete=e3d_seen(complete.shapes, truth, observed),
                e3d_seen_missing=e3d_seen(missing.shapes, truth, observed),
                lost=lost.tolist(), flagged=lost[flagged].tolist(),
                point_fill=fill.tolist(), point_fill_rigid=fill_rigid.tolist(),
                fill_flagged=_mean(fill[flagged]), fill_unflagged=_mean(fill[~flagged]),
                fill_lost=_mean(fill), fill_rigid=_mean(fill_rigid),
                unflagged_bad=int(np.sum(~flagged & (fill > _FILL_BAD))),
                flagged_good=int(np.sum(flagged & (fill < _FILL_GOOD))))


def missing_track_table(rows):
    """The table as (columns, lines, note), one line per task row in the given order
    (:mod:`.report` makes it a Table)."""
    lines = []
    for r in rows:
        ratio = (r["e3d"] / r["e3d_complete"]) if r.get("e3d_complete") else None
        flagged, unflagged, rigid = _ranges(r)
        lines.append([r["sequence"], r["pattern"], r["missing"], r.get("e3d_complete"),
                      r.get("e3d"), ratio, r["e3d_seen_complete"], r["e3d_seen_missing"],
                      len(r["lost"]), len(r["flagged"]), r["fill_flagged"], flagged,
                      r["fill_unflagged"], unflagged, r["fill_lost"], r["fill_rigid"],
                      rigid, r["unflagged_bad"], r["flagged_good"], r["t_total"]])
    fraction = rows[0]["fraction"] if rows else None
    seed = rows[0]["drop_seed"] if rows else None
    note = (f"data_tools.drop_tracks(W, {fraction}, seed={seed}, pattern=...), organic "
            "pipeline at the paper's K. missing: fraction of the entries. e3d seen: over "
            "the points seen in each frame (complete: the complete-data shapes of the same "
            "points). lost points: missing in at least one frame; flagged: of them "
            "unreliable (Reconstruction.unreliable: fill gain above MAX_GAIN and, where "
            "filled from their neighbours, their fills' spread above SPREAD_MAX). fill: a "
            "lost point's mean error over "
            "its unseen frames after e3d's per-frame similarity alignment, RMS shape "
            "radius = 1, mean over the points (flagged, unflagged, all lost) and range "
            "over them; "
            "rigid-neighbour: each lost point carried rigidly with its 4 nearest visible "
            "neighbours from the frame it was last seen in, on the pipeline's shapes "
            "(nrsfm.experiments.fill.rigid_neighbour_fill). Last two: counts of lost "
            f"points with fill above {_FILL_BAD} not flagged, below {_FILL_GOOD} flagged.")
    return COLUMNS, lines, note

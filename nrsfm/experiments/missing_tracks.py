"""The lost-tracks table of the ``missing`` experiment: where the loss of a reconstruction
with missing data is, and how good its fills and its flag are. One task per sequence and
pattern of :func:`data_tools.drop_tracks` (:func:`.tasks.run_missing_tracks`); the fills
are scored for the pipeline and for the rigid-neighbour baseline (:mod:`.fill`).
"""

from __future__ import annotations

import numpy as np

from .fill import e3d_seen, lost_point_means, point_errors, rigid_neighbour_fill

TITLE = "Lost tracks: where the error is, the fills and their flag"

#: the table's columns (:func:`missing_track_table`)
COLUMNS = (
    "sequence|pattern|missing|e3d complete|e3d missing|ratio|e3d seen, complete|"
    "e3d seen, missing|lost points|flagged|fill flagged|range|fill unflagged|range|fill lost|"
    "fill rigid-neighbour|range|fill > .15 unflagged|fill < .05 flagged|s total"
).split("|")

#: fill errors counted as bad when not flagged, and as good when flagged
FILL_BAD, FILL_GOOD = 0.15, 0.05


def _mean(values):
    return float(np.mean(values)) if len(values) else None


def _range(values):
    """``"min-max"`` of some fill errors (two decimals), None for none."""
    return f"{min(values):.2f}-{max(values):.2f}" if len(values) else None


def track_row(complete, missing, truth, observed):
    """The metrics of one sequence and pattern (a dict of JSON values; means None where no
    point is of the kind).

    Parameters
    ----------
    complete, missing : nrsfm.Reconstruction
        The pipeline on the complete W and on W with the missing entries.
    truth : (F, 3, P) ndarray
        Ground-truth shapes.
    observed : (F, P) bool ndarray
        True where a point was seen.
    """
    lost = np.flatnonzero(~observed.all(axis=0))
    flagged = missing.unreliable[lost]
    fill = lost_point_means(point_errors(missing.shapes, truth), observed)[lost]
    rigid = rigid_neighbour_fill(missing.shapes, observed)
    fill_rigid = lost_point_means(point_errors(rigid, truth), observed)[lost]
    return dict(
        e3d_seen_complete=e3d_seen(complete.shapes, truth, observed),
        e3d_seen_missing=e3d_seen(missing.shapes, truth, observed),
        lost=lost.tolist(),
        flagged=lost[flagged].tolist(),
        point_fill=fill.tolist(),
        point_fill_rigid=fill_rigid.tolist(),
        fill_flagged=_mean(fill[flagged]),
        fill_unflagged=_mean(fill[~flagged]),
        fill_lost=_mean(fill),
        fill_rigid=_mean(fill_rigid),
        unflagged_bad=int(np.sum(~flagged & (fill > FILL_BAD))),
        flagged_good=int(np.sum(flagged & (fill < FILL_GOOD))),
    )


def missing_track_table(rows):
    """(columns, lines, note), one line per task row in the given order."""
    lines = []
    for r in rows:
        ratio = (r["e3d"] / r["e3d_complete"]) if r.get("e3d_complete") else None
        flagged = set(r["flagged"])
        fills = list(zip(r["lost"], r["point_fill"]))
        ranges = [_range([x for p, x in fills if (p in flagged) == f]) for f in (True, False)]
        line = [r["sequence"], r["pattern"], r["missing"], r.get("e3d_complete"), r.get("e3d")]
        line += [ratio, r["e3d_seen_complete"], r["e3d_seen_missing"], len(fills), len(flagged)]
        line += [r["fill_flagged"], ranges[0], r["fill_unflagged"], ranges[1], r["fill_lost"]]
        line += [r["fill_rigid"], _range(r["point_fill_rigid"]), r["unflagged_bad"]]
        lines.append(line + [r["flagged_good"], r["t_total"]])
    fraction, seed = (rows[0]["fraction"], rows[0]["drop_seed"]) if rows else (None, None)
    note = (
        f"data_tools.drop_tracks(W, {fraction}, seed={seed}, pattern=...), organic pipeline "
        "at the paper's K. missing: fraction of the entries. e3d seen: over the points seen "
        "in each frame (complete: the complete-data shapes of the same points). lost points: "
        "missing in at least one frame; flagged: of them unreliable (Reconstruction."
        "unreliable: fill gain above MAX_GAIN and, where filled from their neighbours, their "
        "fills' spread above SPREAD_MAX). fill: a lost point's mean error over its unseen "
        "frames after e3d's per-frame similarity alignment, RMS shape radius = 1, mean over "
        "the points (flagged, unflagged, all lost) and range over them; rigid-neighbour: each "
        "lost point carried rigidly with its 4 nearest visible neighbours from the frame it "
        "was last seen in, on the pipeline's shapes (nrsfm.experiments.fill."
        "rigid_neighbour_fill). Last two: counts of lost points with fill above "
        f"{FILL_BAD} not flagged, below {FILL_GOOD} flagged."
    )
    return COLUMNS, lines, note

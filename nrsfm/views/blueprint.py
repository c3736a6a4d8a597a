"""Default layouts (rerun blueprints) of the recordings: pure functions of the content.

:func:`make_blueprint` lays out a reconstruction's recording (:mod:`nrsfm.views.recording`),
:func:`make_video_blueprint` a video run's (:mod:`nrsfm.views.video`). rerun is imported
lazily.
"""

from __future__ import annotations

import numpy as np

from .content import HISTORY_KEYS

__all__ = ["make_blueprint", "make_video_blueprint", "HISTORY_LOG", "history_label"]

#: Shape-stage quantities drawn on a log10 axis (they span many orders of magnitude).
HISTORY_LOG = ("data_term", "residual", "rho", "grad_norm")


def history_label(name):
    """Axis label of a shape-stage history quantity."""
    return f"log10 {name}" if name in HISTORY_LOG else name


def _eye(content):
    """Opening eye of the 3D views: behind and above the first camera, both cameras and
    shapes in view. Returns (position, up) for the world view."""
    R = content.cameras_gt if content.cameras_gt is not None else content.cameras_est
    if R is None or not len(R):
        return np.array([1.0, -1.5, 1.0]) * 2.5 * content.camera_distance, np.array([0, 0, 1.0])
    r1, r2, r3 = R[0]
    direction = -r3 - 0.55 * r2 + 0.45 * r1     # behind camera 0, above it (image y down)
    direction /= np.linalg.norm(direction)
    return 2.2 * content.camera_distance * direction, -r2


def _has(content, attr):
    """Whether ``content`` (None: a layout for any content) holds ``attr``."""
    if content is None:
        return True
    value = getattr(content, attr)
    return value is not None and (not isinstance(value, dict) or bool(value))


def _left_column(rrb, content):
    """The 3D world above; the rotation samples and the image below."""
    world_kw = {}
    if content is not None:
        pos, up = _eye(content)
        world_kw["eye_controls"] = rrb.EyeControls3D(position=pos, look_target=[0, 0, 0],
                                                     eye_up=up)
    gt_shapes = content is None or content.shapes_gt is not None
    top = rrb.Spatial3DView(
        origin="/world", name=("shapes (orange estimate, blue ground truth) and cameras"
                               if gt_shapes else "shapes and cameras (estimate)"), **world_kw)
    lower = []
    if _has(content, "triplet_rotations"):
        lower.append(rrb.Spatial3DView(
            origin="/rotations", name="camera axes: samples (thin), average (thick)" + (
                ", GT (pale)" if content is None or content.rotations_gt_display is not None
                else ""),
            eye_controls=rrb.EyeControls3D(position=[1.7, -2.0, 1.4], look_target=[0, 0, 0],
                                           eye_up=[0, 0, 1])))
    lower.append(rrb.Spatial2DView(origin="/image", name="image: measured (blue) vs "
                                   "reprojected (orange)"))
    return rrb.Vertical(top, rrb.Horizontal(*lower), row_shares=[3, 2])


def _series_views(rrb, content, no_legend):
    """Per-frame errors and rotation-sample series (tabs on the right)."""
    series = []
    errors = (list(content.errors_per_frame) if content is not None else ["e3d", "e_R"])
    for n in errors:
        series.append(rrb.TimeSeriesView(origin=f"/errors/{n}", name=f"{n} per frame",
                                         plot_legend=no_legend))
    if _has(content, "triplet_rotations"):
        series.append(rrb.TimeSeriesView(origin="/rotation_samples/distance",
                                         name="sample distance to average"))
        if content is None or content.triplet_coefficients is not None:
            series.append(rrb.TimeSeriesView(origin="/rotation_samples/coefficient",
                                             name="|c_fk| per triplet"))
        series.append(rrb.TimeSeriesView(
            origin="/rotation_samples", contents=["/rotation_samples/n_kept",
                                                  "/rotation_samples/sign_from_smoothness"],
            name="samples kept, sign flips"))
    return series


def _right_column(rrb, content):
    """Shape-stage history, per-frame series, spectra and report."""
    no_legend = rrb.PlotLegend(visible=False)
    names = (list(content.admm) if content is not None else list(HISTORY_KEYS))
    history = [rrb.BarChartView(origin=f"/admm_history/{n}",
                                name=("shape cost" if n == "cost"
                                      else history_label(n).replace("_", " ")),
                                plot_legend=no_legend)
               for n in names if n in HISTORY_KEYS]
    series = _series_views(rrb, content, no_legend)
    spectra = [rrb.BarChartView(origin=f"/singular_values/{n}", name=title,
                                plot_legend=no_legend)
               for n, title in (("W", "singular values of W"),
                                ("X_init", "singular values of X_init#"),
                                ("log10_theta", "log10 weights theta"))
               if content is None or n in content.singular_values
               or (n == "log10_theta" and "theta" in content.singular_values)]
    report = rrb.TextDocumentView(origin="/run/report", name="report")
    right = []
    if history:
        right.append(rrb.Grid(*history, grid_columns=2, name="shape stage"))
    if series:
        right.append(rrb.Tabs(*series, name="per frame"))
    right.append(rrb.Tabs(*spectra, report, name="spectra and report"))
    shares = [3, 2, 2] if len(right) == 3 else [1] * len(right)
    return rrb.Vertical(*right, row_shares=shares)


def make_blueprint(content=None):
    """The default layout, in which every view has data on the opening timeline ``frame``.

    Left: the 3D world (shapes, cameras as frusta with RGB axes), the rotation samples and
    the image. Right: the shape-stage history as one bar chart per quantity (static, so it
    shows whatever the timeline; data term, residual and rho on log10 axes), per-frame
    errors and rotation-sample series in tabs, the spectra (theta on a log10 axis) and the
    report.

    Parameters
    ----------
    content : nrsfm.views.RecordingContent, optional
        The views of parts the content lacks are left out; None: every view.
    """
    import rerun.blueprint as rrb

    return rrb.Blueprint(
        rrb.Horizontal(_left_column(rrb, content), _right_column(rrb, content),
                       column_shares=[3, 2]),
        rrb.BlueprintPanel(state="collapsed"), rrb.SelectionPanel(state="collapsed"),
        rrb.TimePanel(state="collapsed", timeline="frame"),
        auto_views=False, collapse_panels=False)


def make_video_blueprint(has_gt=False):
    """Frames with tracks left, 3D result right; per-frame series and report below."""
    import rerun.blueprint as rrb

    series = [rrb.TimeSeriesView(origin="/tracks", name="tracks observed")]
    if has_gt:
        series.insert(0, rrb.TimeSeriesView(origin="/errors", name="per-frame e3d"))
    return rrb.Blueprint(
        rrb.Vertical(
            rrb.Horizontal(rrb.Spatial2DView(origin="/video", name="video and tracks"),
                           rrb.Spatial3DView(origin="/world", name="3D reconstruction")),
            rrb.Horizontal(rrb.Tabs(*series),
                           rrb.TextDocumentView(origin="/run/report", name="report")),
            row_shares=[3, 1]),
        collapse_panels=True)

"""Default layouts (rerun blueprints) of the recordings of a reconstruction
(:mod:`.recording`) and of a video run (:mod:`.video`): pure functions of the content."""

from __future__ import annotations

import numpy as np

from .content import HISTORY_KEYS

#: Shape-stage quantities drawn on a log10 axis (they span many orders of magnitude).
HISTORY_LOG = ("data_term", "residual", "rho", "grad_norm")


def _eye(content):
    """(position, up) of the 3D view's eye: behind and above the first camera, so that
    cameras and shapes are in view."""
    R = content.cameras_gt if content.cameras_gt is not None else content.cameras_est
    if R is None or not len(R):
        return np.array([1.0, -1.5, 1.0]) * 2.5 * content.camera_distance, np.array([0, 0, 1.0])
    r1, r2, r3 = R[0]
    direction = -r3 - 0.55 * r2 + 0.45 * r1  # behind camera 0, above it (image y down)
    return 2.2 * content.camera_distance * direction / np.linalg.norm(direction), -r2


def _has(content, attr):
    """Whether ``content`` (None: a layout for any content) holds ``attr``."""
    if content is None:
        return True
    value = getattr(content, attr)
    return value is not None and (not isinstance(value, dict) or bool(value))


def _left_column(rrb, content):
    """The 3D world above; the rotation samples and the image below."""
    kw = {}
    if content is not None:
        pos, up = _eye(content)
        kw["eye_controls"] = rrb.EyeControls3D(position=pos, look_target=[0, 0, 0], eye_up=up)
    if content is None or content.shapes_gt is not None:
        name = "shapes (orange estimate, blue ground truth) and cameras"
    else:
        name = "shapes and cameras (estimate)"
    lower = []
    if _has(content, "triplet_rotations"):
        gt = content is None or content.rotations_gt_display is not None
        eye = rrb.EyeControls3D(position=[1.7, -2.0, 1.4], look_target=[0, 0, 0], eye_up=[0, 0, 1])
        axes = "camera axes: samples (thin), average (thick)" + ", GT (pale)" * gt
        lower.append(rrb.Spatial3DView(origin="/rotations", name=axes, eye_controls=eye))
    image = "image: measured (blue) vs reprojected (orange)"
    lower.append(rrb.Spatial2DView(origin="/image", name=image))
    top = rrb.Spatial3DView(origin="/world", name=name, **kw)
    return rrb.Vertical(top, rrb.Horizontal(*lower), row_shares=[3, 2])


def _series_views(rrb, content, no_legend):
    """Per-frame errors and rotation-sample series (tabs on the right)."""
    errors = list(content.errors_per_frame) if content is not None else ["e3d", "e_R"]
    series = [
        rrb.TimeSeriesView(origin=f"/errors/{n}", name=f"{n} per frame", plot_legend=no_legend)
        for n in errors
    ]
    if _has(content, "triplet_rotations"):
        path, name = "/rotation_samples/angle", "sample angle to the average (rad)"
        series.append(rrb.TimeSeriesView(origin=path, name=name))
        if content is None or content.triplet_coefficients is not None:
            path, name = "/rotation_samples/coefficient", "|c_fk| per triplet"
            series.append(rrb.TimeSeriesView(origin=path, name=name))
        paths = ["/rotation_samples/n_kept", "/rotation_samples/sign_from_smoothness"]
        name = "samples kept, sign flips"
        series.append(rrb.TimeSeriesView(origin="/rotation_samples", contents=paths, name=name))
    return series


def _right_column(rrb, content):
    """Shape-stage history, per-frame series, spectra and report."""
    no_legend = rrb.PlotLegend(visible=False)
    names = [
        n for n in (content.admm if content is not None else HISTORY_KEYS) if n in HISTORY_KEYS
    ]
    history = []
    for n in names:
        name = (
            "shape cost" if n == "cost" else ("log10 " * (n in HISTORY_LOG) + n).replace("_", " ")
        )
        path = f"/shape_history_bars/{n}"
        history.append(rrb.BarChartView(origin=path, name=name, plot_legend=no_legend))
    spectra = []
    titles = dict(W="singular values of W", X_init="singular values of X_init#")
    for n, title in dict(titles, log10_theta="log10 weights theta").items():
        if content is None or n.replace("log10_", "") in content.singular_values:
            path = f"/singular_values/{n}"
            spectra.append(rrb.BarChartView(origin=path, name=title, plot_legend=no_legend))
    report = rrb.TextDocumentView(origin="/run/report", name="report")
    right = [rrb.Grid(*history, grid_columns=2, name="shape stage")] if history else []
    series = _series_views(rrb, content, no_legend)
    right += [rrb.Tabs(*series, name="per frame")] if series else []
    right.append(rrb.Tabs(*spectra, report, name="spectra and report"))
    return rrb.Vertical(*right, row_shares=[3, 2, 2] if len(right) == 3 else [1] * len(right))


def _perspective_eye(content):
    """(position, target, up) of the 3D view's eye for a perspective result: beside and
    above the middle of the cameras' centres and the object, far enough to hold them all."""
    centres = content.camera_centres
    mean = centres.mean(axis=0)
    ahead = mean / max(float(np.linalg.norm(mean)), 1e-12)  # from the object to the cameras
    up = -content.cameras_est[:, 1].mean(axis=0)  # image y points down
    up = up - (up @ ahead) * ahead
    up = up / max(float(np.linalg.norm(up)), 1e-12)
    side = np.cross(up, ahead)
    target = 0.5 * mean
    reach = max(float(np.max(np.linalg.norm(centres - target, axis=1))), 1e-12)
    position = target + 2.0 * reach * (0.8 * side + 0.45 * up + 0.4 * ahead)
    return position, target, up


def make_perspective_blueprint(content=None):
    """The layout of a perspective result: the 3D world with the cameras (their frusta and
    trajectory) and the shapes, largest, left; right the image in pixels (tracks, the
    orthographic start's and the perspective projection), the two per-frame reprojection
    RMS curves, and the refinement's cost history (static bars, log10) beside the report.
    Every view has data on the opening timeline ``frame``."""
    import rerun.blueprint as rrb

    kw, no_legend = {}, rrb.PlotLegend(visible=False)
    if content is not None:
        pos, target, up = _perspective_eye(content)
        kw["eye_controls"] = rrb.EyeControls3D(position=pos, look_target=target, eye_up=up)
    gt = content is None or content.shapes_gt is not None
    name = "cameras (frusta, trajectory) and shapes" + " (orange estimate, blue truth)" * gt
    world = rrb.Spatial3DView(origin="/world", name=name, **kw)
    image = "image (px): tracks (blue), orthographic start (green), perspective (orange)"
    name = "reprojection RMS (px): orthographic (green), perspective (orange)"
    rms = rrb.TimeSeriesView(origin="/reprojection", name=name, plot_legend=no_legend)
    bars = [
        rrb.BarChartView(origin=f"/perspective_history_bars/{n}", name=t, plot_legend=no_legend)
        for n, t in (("cost", "log10 cost E per iteration"), ("data_term", "log10 data term"))
    ]
    report = rrb.TextDocumentView(origin="/run/report", name="report")
    right = rrb.Vertical(
        rrb.Spatial2DView(origin="/image", name=image),
        rms,
        rrb.Tabs(*bars, report, name="perspective refinement"),
        row_shares=[5, 3, 3],
    )
    return rrb.Blueprint(
        rrb.Horizontal(world, right, column_shares=[3, 2]),
        rrb.BlueprintPanel(state="collapsed"),
        rrb.SelectionPanel(state="collapsed"),
        rrb.TimePanel(state="collapsed", timeline="frame"),
        auto_views=False,
        collapse_panels=False,
    )


def make_blueprint(content=None):
    """The default layout, in which every view has data on the opening timeline ``frame``:
    left the 3D world, the rotation samples and the image; right the shape-stage history
    (static bar charts), per-frame errors and rotation-sample series in tabs, the spectra and
    the report. Views of parts the :class:`.content.RecordingContent` lacks are left out
    (``content`` None: every view). A perspective result's content gets
    :func:`make_perspective_blueprint`."""
    import rerun.blueprint as rrb

    if content is not None and content.perspective:
        return make_perspective_blueprint(content)
    return rrb.Blueprint(
        rrb.Horizontal(
            _left_column(rrb, content), _right_column(rrb, content), column_shares=[3, 2]
        ),
        rrb.BlueprintPanel(state="collapsed"),
        rrb.SelectionPanel(state="collapsed"),
        rrb.TimePanel(state="collapsed", timeline="frame"),
        auto_views=False,
        collapse_panels=False,
    )


def make_video_blueprint(has_gt=False):
    """Frames with tracks left, 3D result right; per-frame series and report below."""
    import rerun.blueprint as rrb

    series = [rrb.TimeSeriesView(origin="/tracks", name="tracks observed")]
    if has_gt:
        series.insert(0, rrb.TimeSeriesView(origin="/errors", name="per-frame e3d"))
    video = rrb.Spatial2DView(origin="/video", name="video and tracks")
    world = rrb.Spatial3DView(origin="/world", name="3D reconstruction")
    report = rrb.TextDocumentView(origin="/run/report", name="report")
    below = rrb.Horizontal(rrb.Tabs(*series), report)
    return rrb.Blueprint(
        rrb.Vertical(rrb.Horizontal(video, world), below, row_shares=[3, 1]), collapse_panels=True
    )

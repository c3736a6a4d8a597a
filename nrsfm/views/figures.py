"""Matplotlib figures of a reconstruction (shapes, cameras, shape-stage history, spectra),
for ``tools/render_figures.py`` and the notebooks; each function returns a new figure. The
display alignment is that of the recordings (:func:`.content.recording_content`)."""

from __future__ import annotations

import numpy as np

EST, GT = "#ff8c00", "#4682ff"

_HISTORY_TITLES = {
    "cost": "cost (Eq. 7 / 8 / 10 by prior)",
    "data_term": "data term 1/2||W-RX||^2",
    "residual": "residual max|X# - Phi(X)|",
    "rho": "penalty rho",
    "grad_norm": "relative gradient norm",
}


def _content(result, sequence, content):
    if content is not None:
        return content
    from .content import recording_content

    return recording_content(result, sequence)


def _equal_3d(ax, pts):
    c = pts.reshape(-1, 3)
    mid, r = (c.max(0) + c.min(0)) / 2, (c.max(0) - c.min(0)).max() / 2
    for set_lim, m in zip((ax.set_xlim, ax.set_ylim, ax.set_zlim), mid):
        set_lim(m - r, m + r)


def shapes_figure(result, sequence=None, frames=None, content=None, title=None):
    """Reconstructed shapes (orange dots) over the ground truth (blue rings), a few frames."""
    import matplotlib.pyplot as plt

    c = _content(result, sequence, content)
    frames = np.linspace(0, c.n_frames - 1, 4).astype(int) if frames is None else frames
    fig = plt.figure(figsize=(3.2 * len(frames), 3.6))
    e = c.errors_per_frame.get("e3d")
    for i, f in enumerate(frames):
        ax = fig.add_subplot(1, len(frames), i + 1, projection="3d")
        sets = [(c.shapes_est[f], EST, "estimate")]
        if c.shapes_gt is not None:  # hollow rings, so that an exact fit stays visible
            sets.insert(0, (c.shapes_gt[f], GT, "ground truth"))
            kw = dict(s=42, facecolors="none", edgecolors=GT, linewidths=1.2)
            ax.scatter(*c.shapes_gt[f].T, label="ground truth", depthshade=False, **kw)
        ax.scatter(*c.shapes_est[f].T, s=8, c=EST, label="estimate", depthshade=False)
        for pts, col, _ in sets:
            for a, b in c.edges if c.edges is not None else []:
                ax.plot(*pts[[a, b]].T, c=col, lw=1)
        _equal_3d(ax, np.concatenate([s[0] for s in sets]))
        ax.set_title(f"frame {f}" + (f"  e3d {e[f]:.3g}" if e is not None else ""), fontsize=9)
        ax.set_xticklabels([]), ax.set_yticklabels([]), ax.set_zticklabels([])
        if i == 0:
            ax.legend(fontsize=8, loc="upper left")
    aligned = " (similarity-aligned per frame)" if c.aligned else ""
    fig.suptitle(title or f"{result.method}: shapes{aligned}", fontsize=10)
    fig.tight_layout()
    return fig


def cameras_figure(result, sequence=None, content=None, title=None):
    """Camera viewing directions r3_f on the unit sphere, and per-frame e_R if known."""
    import matplotlib.pyplot as plt

    c = _content(result, sequence, content)
    has_err = "e_R" in c.errors_per_frame
    fig = plt.figure(figsize=(9 if has_err else 4.5, 4))
    ax = fig.add_subplot(1, 2 if has_err else 1, 1, projection="3d")
    if c.cameras_gt is not None:
        ax.plot(*c.cameras_gt[:, 2].T, c=GT, lw=2.5, label="ground truth")
    z = c.cameras_est[:, 2]
    ax.plot(*z.T, c=EST, lw=1.2, ls="--", label="estimate")
    ax.scatter(*z[0], c="k", s=15, label="frame 0")
    ax.set_title("camera viewing direction r3 per frame", fontsize=9)
    ax.legend(fontsize=8)
    ax.set(xlim=(-1, 1), ylim=(-1, 1), zlim=(-1, 1))
    if has_err:
        ax2 = fig.add_subplot(1, 2, 2)
        ax2.plot(c.errors_per_frame["e_R"], c=EST)
        ax2.set(xlabel="frame", ylabel="e_R per frame")
        ax2.set_title(f"rotation error, mean {c.errors['e_R']:.3g}", fontsize=9)
        ax2.grid(alpha=0.3)
    fig.suptitle(title or f"{result.method}: cameras (globally aligned)", fontsize=10)
    fig.tight_layout()
    return fig


def admm_figure(results, labels=None, title=None):
    """Shape-stage history of one or several runs (log axes): cost, data term and, for the
    ADMM, residual and rho, for the bilinear solver the relative gradient norm."""
    import matplotlib.pyplot as plt

    results = results if isinstance(results, (list, tuple)) else [results]
    labels = labels or [r.method for r in results]
    hists = [getattr(getattr(r, "shape_stage", r), "history", None) or {} for r in results]
    keys = [k for k in _HISTORY_TITLES if any(k in h for h in hists)] or ["cost"]
    fig, axes = plt.subplots(1, len(keys), figsize=(3.5 * len(keys), 3.3), squeeze=False)
    axes, floor = axes[0], np.inf
    for hist, lab in zip(hists, labels):
        for ax, key in zip(axes, keys):
            v = np.asarray(hist.get(key, []), float)
            if (v > 0).any():  # exact fits reach 0: not on a log axis
                ax.semilogy(np.where(v > 0, v, np.nan), label=lab)
        dt = np.asarray(hist.get("data_term", []), float)[1:]
        if (dt > 0).any():
            floor = min(floor, dt[dt > 0].min())
    if np.isfinite(floor) and "data_term" in keys:  # a start that fits W exactly: 1e-30
        axes[keys.index("data_term")].set_ylim(bottom=floor / 10)
    for ax, key in zip(axes, keys):
        ax.set_title(_HISTORY_TITLES[key], fontsize=9)
        ax.set_xlabel("iteration")
        ax.grid(alpha=0.3)
    axes[0].legend(fontsize=8)
    fig.suptitle(title or "shape stage: history", fontsize=10)
    fig.tight_layout()
    return fig


def singular_values_figure(values, labels=None, title=None, mark=None):
    """Singular value spectra (log scale); ``mark``: a line after that many values."""
    import matplotlib.pyplot as plt

    values = [values] if isinstance(values, np.ndarray) and values.ndim == 1 else values
    labels = labels or [None] * len(values)
    fig, ax = plt.subplots(figsize=(6, 3.3))
    for v, lab in zip(values, labels):
        v = np.asarray(v, float)
        ax.semilogy(np.arange(1, v.size + 1), np.maximum(v, 1e-17), "o-", ms=3, label=lab)
    if mark:
        ax.axvline(mark + 0.5, c="gray", ls=":")
    ax.set(xlabel="index i", ylabel="sigma_i")
    ax.grid(alpha=0.3)
    if any(labels):
        ax.legend(fontsize=8)
    ax.set_title(title or "singular values", fontsize=10)
    fig.tight_layout()
    return fig

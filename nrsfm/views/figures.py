"""Matplotlib figures for the lessons: a reconstruction's shapes over the ground truth and
singular value spectra; each function returns a new figure. The display alignment is that
of the recordings (:func:`.content.recording_content`)."""

from __future__ import annotations

import numpy as np

EST, GT = "#ff8c00", "#4682ff"


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

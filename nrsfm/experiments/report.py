"""The benchmark's tables (Markdown and CSV) and plots (PNG) from the task rows."""

from __future__ import annotations

import csv
import io
import math
from collections import Counter
from pathlib import Path

import numpy as np

from ..io import write_text
from ..published import published_value as pub
from .missing_tracks import TITLE as TRACKS_TITLE
from .missing_tracks import missing_track_table
from .plan import paper_K
from .perspective import TITLE as PERSPECTIVE_TITLE
from .perspective import perspective_table
from .shape import TITLE as SHAPE_TITLE
from .shape import shape_table

#: method -> its column in the paper's tables
_PAPER_COLUMN = {"organic": "ours", "organic-admm": "ours", "bmm": "BMM", "wnn": "R-BMM"}

#: table -> (title, columns separated by "|", note)
SPECS = {
    "mocap": (
        "MoCap benchmark (paper's K)",
        "sequence|K|method|e3d|paper e3d|ratio|e3d_akhter|e_R|paper e_R|s factorize|s rotations|"
        "s shape|s total",
        "Paper columns: the organic-priors paper's MoCap table (organic: 'ours', bmm: 'BMM' as "
        "the paper quotes it, under Akhter's metric; wnn: 'R-BMM'). organic-admm: the organic "
        "pipeline with the paper's continuation ADMM instead of the default bilinear shape "
        "solver. e_R only where the ground-truth cameras move (drink, pickup, yoga, stretch).",
    ),
    "mocap_dai_k": (
        "BMM with Dai et al.'s K beside Dai's code run by a peer",
        "sequence|K|e3d_akhter|peer e3d_akhter|ratio|e_R|peer e_R|s total|peer s total",
        "Peer: Dai et al.'s released BMM code under GNU Octave on a 2-core machine "
        "(nrsfm.published, section peer_bmm_octave).",
    ),
    "pseudo_inverse": (
        "Table 1: pseudo-inverse shape (rank-K truncated pinv(R) W)",
        "sequence|K|rotations|e3d|paper ours-PI|ratio|e3d_akhter|paper BMM-PI (Akhter metric)",
        "Rotations: ground truth where the file has them (dance: its fixed camera), else the "
        "organic rotation stage's.",
    ),
    "rotation_ablation": (
        "Table 6: rotation ablation (organic shape stage on each rotation)",
        "rotations",
        "Every e3d row runs the same organic shape stage; only the rotations differ.",
    ),
    "noise": (
        "Noise on {} (Fig. 4a-b)",
        "sigma|method|runs|e_R mean|e_R std|e3d mean|e3d std",
        "Gaussian noise on W with std sigma x (mean row std of W); each run its own seed, the "
        "same noise for every method.",
    ),
    "missing": (
        "Missing data (30%, Fig. 4c)",
        "sequence|pattern|method|missing|fill error|e3d|complete-data e3d|ratio|e_R|"
        "s completion|s total",
        "uniform: each point-frame missing with probability 0.3; tracking: each track lost "
        "with probability 0.3 from a random frame to the end. fill error: "
        "||W_completed - W|| / ||W|| over the missing entries.",
    ),
    "missing_curve": (
        "Missing data curve on {} (uniform)",
        "method|fraction|missing|fill error|e3d|ratio to complete|e_R",
        "",
    ),
    "n_ablation": (
        "N ablation (Fig. 4d): e3d, same organic rotations",
        "sequence",
        "N = 0 penalises every singular value (weighted nuclear norm); the paper uses N = 1.",
    ),
    "k_sweep": (
        "K sweep (organic pipeline): e3d per K",
        "sequence|paper K|best K|best e3d|K:e3d",
        "",
    ),
}


class Table:
    """A titled table: column names, rows (lists of values) and a note."""

    def __init__(self, name, title, columns, rows, note=""):
        self.name, self.title, self.note = name, title, note
        self.columns, self.rows = list(columns), [list(r) for r in rows]

    def markdown(self, level=1):
        """The table as Markdown under a heading of ``level`` (1 on its own page)."""
        lines = [f"{'#' * level} {self.title}", ""] + ([self.note, ""] if self.note else [])
        lines += ["| " + " | ".join(self.columns) + " |", "|" + "---|" * len(self.columns)]
        lines += ["| " + " | ".join(map(_fmt, r)) + " |" for r in self.rows]
        return "\n".join(lines) + "\n"

    def csv(self):
        buf = io.StringIO()
        rows = [["" if v is None else v for v in r] for r in self.rows]
        csv.writer(buf, lineterminator="\n").writerows([self.columns] + rows)
        return buf.getvalue()


def _fmt(v):
    if v is None or (isinstance(v, float) and math.isnan(v)):
        return "-"
    if isinstance(v, float):
        return "0" if v == 0 else f"{v:.4f}" if abs(v) >= 1e-3 else f"{v:.2e}"
    return str(v)


def _table(name, rows, subject=None, columns=()):
    """The table ``name`` of :data:`SPECS` (``subject`` fills its title, ``columns`` are
    added to its own)."""
    title, names, note = SPECS[name]
    return Table(name, title.format(subject), names.split("|") + list(columns), rows, note)


def _ratio(a, b):
    return None if a is None or not b else a / b


def _get(rows, **match):
    """The first row with the given values, or None."""
    return next((r for r in rows if all(r.get(k) == v for k, v in match.items())), None)


def _e3d(row):
    return None if row is None else row.get("e3d")


def _mean_std(rows, key):
    vals = [r.get(key) for r in rows if r.get(key) is not None]
    return (float(np.mean(vals)), float(np.std(vals))) if vals else (None, None)


def _mocap(rows, seqs):
    from data_tools import DAI_K

    body = []
    for n in seqs:
        for m, col in _PAPER_COLUMN.items():
            r = _get(rows, sequence=n, method=m, K=paper_K(n))
            if r is not None:
                paper, e = pub("mocap_e3d", col, n), r.get("e3d")
                line = [n, r["K"], m, e, paper, _ratio(e, paper), r.get("e3d_akhter")]
                line += [r.get("e_R"), pub("mocap_rotation_error", col, n)]
                times = [r.get(f"t_{s}") for s in ("factorize", "rotations", "shape", "total")]
                body.append(line + times)
    mocap = _table("mocap", body)
    body = []
    for n in seqs:
        r = _get(rows, sequence=n, method="bmm", K=DAI_K[n]) if n in DAI_K else None
        if r is not None:
            peer = {c: pub("peer_bmm_octave", c, n) for c in ("e3d_akhter", "e_R", "time_total_s")}
            e = r.get("e3d_akhter")
            line = [n, DAI_K[n], e, peer["e3d_akhter"], _ratio(e, peer["e3d_akhter"])]
            body.append(line + [r.get("e_R"), peer["e_R"], r.get("t_total"), peer["time_total_s"]])
    dai = _table("mocap_dai_k", body)
    return [mocap, dai]


def _pseudo_inverse(rows, seqs):
    body = []
    for n in seqs:
        r = _get(rows, sequence=n)
        if r is not None:
            paper, e = pub("mocap_pseudo_inverse_e3d", "ours-PI", n), r.get("e3d")
            line = [n, r["K"], r["rotations"], e, paper, _ratio(e, paper), r.get("e3d_akhter")]
            body.append(line + [pub("mocap_pseudo_inverse_e3d", "BMM-PI", n)])
    return _table("pseudo_inverse", body)


def _rotation_ablation(rows, seqs):
    seqs = [n for n in seqs if _get(rows, sequence=n)]
    srcs = [s for s in ("bmm", "organic", "ground_truth") if _get(rows, rotations=s)]
    ablation = "mocap_e3d_rotation_ablation"

    def cells(key, s):
        return [(_get(rows, sequence=n, rotations=s) or {}).get(key) for n in seqs]

    names = {"bmm": "BMM", "organic": "organic", "ground_truth": "ground-truth"}
    body = [[f"e3d, {names[s]} rotation"] + cells("e3d", s) for s in srcs]
    body.append(["paper: BMM"] + [pub("mocap_e3d", "BMM", n) for n in seqs])
    for label in ("Dai", "our"):
        col = f"ours_shape_with_{label.lower()}_rotation"
        body.append([f"paper: e3d, {label} rotation"] + [pub(ablation, col, n) for n in seqs])
    body += [[f"e_R, {s} rotation"] + cells("e_R", s) for s in srcs if s != "ground_truth"]
    return _table("rotation_ablation", body, columns=seqs)


def _noise(rows, figures):
    seq, sigmas = rows[0]["sequence"], sorted({r["sigma"] for r in rows})
    methods = [m for m in _PAPER_COLUMN if _get(rows, method=m)]
    body, stats = [], {}
    for sg in sigmas:
        for m in methods:
            sel = [r for r in rows if r["sigma"] == sg and r["method"] == m]
            stats[sg, m] = _mean_std(sel, "e_R"), _mean_std(sel, "e3d")
            body.append([sg, m, len(sel), *stats[sg, m][0], *stats[sg, m][1]])

    def draw(plt):
        fig, axes = plt.subplots(1, 2, figsize=(9, 3.4))
        for ax, j, label in ((axes[0], 0, "e_R"), (axes[1], 1, "e3d")):
            for m in methods:
                mu = np.array([stats[s, m][j][0] or np.nan for s in sigmas], float)
                sd = np.array([stats[s, m][j][1] or 0.0 for s in sigmas], float)
                ax.plot(sigmas, mu, "o-", label=m)
                ax.fill_between(sigmas, mu - sd, mu + sd, alpha=0.2)
            ax.set(xlabel="noise sigma (x mean row std of W)", ylabel=label)
            ax.set_title(f"{label} vs noise, {seq}")
            ax.legend()
        return fig

    figures["noise"] = draw
    return _table("noise", body, seq)


def _missing(rows, complete, seqs, figures):
    """The missing-data table at 30% and the curve on the sequence that has one; ``complete``:
    the complete-data rows at the paper's K."""

    def base(n, m):
        return _e3d(_get(complete, sequence=n, method=m))

    body = []
    for n in seqs:
        for pt in ("uniform", "tracking"):
            for m in ("organic", "bmm"):
                r = _get(rows, sequence=n, pattern=pt, method=m, fraction=0.3)
                if r is not None:
                    b, e = base(n, m), r.get("e3d")
                    line = [n, pt, m, r["missing"], r["fill_error"], e, b, _ratio(e, b)]
                    body.append(line + [r.get("e_R"), r.get("t_completion"), r.get("t_total")])
    tables = [_table("missing", body)]
    curve = [r for r in rows if r["pattern"] == "uniform"]
    if not curve:
        return tables
    count = Counter(r["sequence"] for r in curve)
    seq = max(count, key=count.get)
    body, pts = [], {}
    curve = sorted(
        (r for r in curve if r["sequence"] == seq), key=lambda r: (r["method"], r["fraction"])
    )
    for r in curve:
        b, e = base(seq, r["method"]), r.get("e3d")
        line = [r["method"], r["fraction"], r["missing"], r["fill_error"], e, _ratio(e, b)]
        body.append(line + [r.get("e_R")])
        pts.setdefault(r["method"], []).append((r["fraction"], e, b))

    def draw(plt):
        fig, ax = plt.subplots(figsize=(4.8, 3.4))
        for m, p in pts.items():
            p = sorted(p)
            ax.plot([x[0] for x in p], [x[1] for x in p], "o-", label=m)
            if p[0][2] is not None:
                ax.axhline(p[0][2], ls=":", color=ax.lines[-1].get_color(), lw=1)
        ax.set(xlabel="fraction of point observations missing", ylabel="e3d")
        ax.set_title(f"missing data, {seq} (dotted: complete data)")
        ax.legend()
        return fig

    figures["missing_curve"] = draw
    return tables + [_table("missing_curve", body, seq)]


def _n_ablation(rows, figures):
    seqs, Ns = list(dict.fromkeys(r["sequence"] for r in rows)), sorted({r["N"] for r in rows})
    e3d = {n: [_e3d(_get(rows, sequence=n, N=N)) for N in Ns] for n in seqs}

    def draw(plt):
        fig, ax = plt.subplots(figsize=(4.8, 3.4))
        for n in seqs:
            ax.plot(Ns, np.array(e3d[n], float), "o-", label=n)
        ax.set(yscale="log", xlabel="N (leading singular values not penalised)", ylabel="e3d")
        ax.set_title("N ablation")
        ax.legend(fontsize=7)
        return fig

    if rows:
        figures["n_ablation"] = draw
    columns = [f"N={N}" for N in Ns]
    return _table("n_ablation", [[n] + e3d[n] for n in seqs], columns=columns)


def _k_sweep(rows, figures):
    from data_tools import MOCAP_K

    seqs = dict.fromkeys(r["sequence"] for r in rows)
    by_seq = {
        n: sorted((r for r in rows if r["sequence"] == n), key=lambda r: r["K"]) for n in seqs
    }
    body = []
    for n, sel in by_seq.items():
        best = min(sel, key=lambda r: r.get("e3d", np.inf))
        curve = " ".join(f"{r['K']}:{r.get('e3d', float('nan')):.4f}" for r in sel)
        body.append([n, MOCAP_K.get(n), best["K"], best.get("e3d"), curve])

    def draw(plt):
        fig, ax = plt.subplots(figsize=(5.5, 3.6))
        for n, sel in by_seq.items():
            Ks, e3d = [r["K"] for r in sel], [r.get("e3d", np.nan) for r in sel]
            (line,) = ax.plot(Ks, e3d, ".-", label=n)
            rp = _get(sel, K=MOCAP_K.get(n))
            if rp:
                ax.plot([rp["K"]], [rp["e3d"]], "o", mfc="none", color=line.get_color(), ms=9)
        ax.set(yscale="log", xlabel="K", ylabel="e3d", title="K sweep (o: paper's K)")
        ax.legend(fontsize=7, ncol=2)
        return fig

    if rows:
        figures["k_sweep"] = draw
    return _table("k_sweep", body)


def build_tables(plan, results, sequences):
    """The tables and figures (name -> function of pyplot returning a figure) of a plan's
    results (task key -> rows)."""

    def rows_of(exp, kind=None):
        keys = dict.fromkeys(t.key for t in plan.get(exp, []) if kind in (None, t.experiment))
        return [r for k in keys for r in results.get(k, [])]

    tables, figures = [], {}
    if "mocap" in plan:
        tables += _mocap(rows_of("mocap"), sequences)
    if "pseudo_inverse" in plan:
        tables.append(_pseudo_inverse(rows_of("pseudo_inverse"), sequences))
    if "rotation_ablation" in plan:
        tables.append(_rotation_ablation(rows_of("rotation_ablation"), sequences))
    if "noise" in plan and rows_of("noise"):
        tables.append(_noise(rows_of("noise"), figures))
    if "missing" in plan:
        complete = rows_of("mocap") + rows_of("missing", "mocap")
        complete = [r for r in complete if r["K"] == paper_K(r["sequence"])]
        tables += _missing(rows_of("missing", "missing"), complete, sequences, figures)
        if rows_of("missing", "missing_tracks"):
            columns, lines, note = missing_track_table(rows_of("missing", "missing_tracks"))
            tables.append(Table("missing_tracks", TRACKS_TITLE, columns, lines, note))
    if "n_ablation" in plan:
        tables.append(_n_ablation(rows_of("n_ablation"), figures))
    if "k_sweep" in plan:
        tables.append(_k_sweep(rows_of("k_sweep"), figures))
    if "shape" in plan:
        tables.append(Table("shape", SHAPE_TITLE, *shape_table(rows_of("shape"))))
    if "perspective" in plan and rows_of("perspective"):
        rows = rows_of("perspective")
        tables.append(Table("perspective", PERSPECTIVE_TITLE, *perspective_table(rows)))
    return tables, figures


def write_report(out, plan, results, sequences, header=""):
    """Write every table (``NAME.md``, ``NAME.csv``), the plots (``NAME.png``) and
    ``README.md`` (all of them) into ``out``; returns (file names, tables)."""
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    tables, figures = build_tables(plan, results, sequences)
    files = []
    for t in tables:
        write_text(out / f"{t.name}.md", t.markdown())
        write_text(out / f"{t.name}.csv", t.csv())
        files += [f"{t.name}.md", f"{t.name}.csv"]
    if figures:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt

        for name, draw in figures.items():
            fig = draw(plt)
            fig.tight_layout()
            fig.savefig(out / f"{name}.png", dpi=90)
            plt.close(fig)
    pngs = [f"{name}.png" for name in figures]
    doc = ([header] if header else []) + [t.markdown(level=2) for t in tables]
    write_text(out / "README.md", "\n".join(doc + [f"![{p[:-4]}]({p})\n" for p in pngs]))
    return files + pngs + ["README.md"], tables

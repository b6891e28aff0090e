"""Figures of experiment ``breechface``: ROC curves, score distributions, the pair panels."""
from __future__ import annotations

import base64

import numpy as np

SAME, OTHER = "#1a9850", "#7f7f7f"


_INTEGRATORS = ("poisson", "bilateral")


def _labels(scores):
    """(method, integrator) groups in the study's method order, a method's integrators
    side by side, the scans (the upper bound) last; stored order would vary per store."""
    from psbench.forensic.breechface_runs import LABELS

    groups = list(dict.fromkeys(zip(scores["method"], scores["integrator"])))
    order = {m: i for i, m in enumerate(LABELS)}
    rank = {g: i for i, g in enumerate(groups)}   # labels not in LABELS keep their order

    def key(g):
        m, integ = g
        integ_rank = _INTEGRATORS.index(integ) if integ in _INTEGRATORS else 2
        return (m == "scan", order.get(m, len(order)), integ_rank, rank[g])
    return sorted(groups, key=key)


def _tick(m, integ):
    # three short lines, not one long rotated one: 15 groups fit a panel
    return _name(m, integ).replace("weighted ", "weighted\n").replace(" / ", "\n")


def _name(m, integ):
    return m if integ == "-" else f"{m} / {integ}"


def _finishes(scores):
    return sorted(set(scores["finish"]) - {"-"}) or ["-"]


def _of(scores, finish):
    return scores[(scores["finish"] == finish) | (scores["finish"] == "-")]


def roc(positive, negative):
    """(false positive rate, true positive rate) of every threshold of a score."""
    p = np.asarray(positive, float)
    q = np.asarray(negative, float)
    p, q = p[np.isfinite(p)], q[np.isfinite(q)]
    ts = np.unique(np.concatenate([p, q]))[::-1]
    tpr = [0.0] + [float((p >= t).mean()) for t in ts] + [1.0]
    fpr = [0.0] + [float((q >= t).mean()) for t in ts] + [1.0]
    return np.array(fpr), np.array(tpr)


def roc_figure(scores):
    """ROC of the CMC count (top) and of CCFmax (bottom), one column per finish."""
    from psbench.report.figures import new_figure

    fins = _finishes(scores)
    fig, axes = new_figure(ncols=len(fins), nrows=2, w=6.0, h=5.0)
    axes = np.asarray(axes).reshape(2, len(fins))
    for j, fin in enumerate(fins):
        d = _of(scores, fin)
        for i, (col, what) in enumerate((("count", "CMC count"), ("ccf", "CCFmax"))):
            ax = axes[i, j]
            labels = _labels(d)
            # one colour per method, the line style tells the integrator
            colour = {m: f"C{c % 10}" for c, m in enumerate(dict.fromkeys(m for m, _ in labels))}
            for m, integ in labels:
                g = d[(d["method"] == m) & (d["integrator"] == integ)]
                s, n = g.loc[g["same_gun"], col], g.loc[~g["same_gun"], col]
                if not len(s) or not len(n):
                    continue
                x, y = roc(s, n)
                kw = {"color": "black", "lw": 5, "alpha": 0.35} if m == "scan" else {
                    "color": colour[m], "ls": "--" if integ == "bilateral" else "-"}
                ax.plot(x, y, drawstyle="steps-post", label=_name(m, integ), **kw)
            ax.plot([0, 1], [0, 1], color="0.8", lw=0.8)
            ax.set_xlabel("false positive rate (different-gun pairs)")
            ax.set_ylabel("true positive rate (same-gun pairs)")
            ax.set_title(f"{fin}: ROC of the {what}", fontsize=12)
            ax.grid(True, alpha=0.3)
    axes[0, 0].legend(fontsize=9, loc="lower right")
    return fig


def score_figure(scores):
    """CMC count and CCFmax of every pair per method (same gun green, different grey)."""
    from psbench.report.figures import new_figure

    fins = _finishes(scores)
    labels = _labels(scores)
    fig, axes = new_figure(ncols=1, nrows=2 * len(fins), w=max(10.0, 0.85 * len(labels) + 2),
                           h=4.0)
    axes = np.atleast_1d(np.asarray(axes).ravel())
    rng = np.random.default_rng(0)
    k = 0
    for fin in fins:
        d = _of(scores, fin)
        for col, what in (("count", "CMC count"), ("ccf", "CCFmax")):
            ax = axes[k]
            k += 1
            for i, (m, integ) in enumerate(labels):
                g = d[(d["method"] == m) & (d["integrator"] == integ)]
                for same, colour, dx in ((False, OTHER, -0.12), (True, SAME, 0.12)):
                    v = g.loc[g["same_gun"] == same, col].to_numpy(float)
                    x = i + dx + rng.uniform(-0.07, 0.07, v.size)
                    ax.plot(x, v, "o", ms=4, color=colour, alpha=0.7,
                            label=("same gun" if same else "different guns") if i == 0
                            else None)
            if col == "count":
                from psbench.forensic.cmc import CMC_THRESHOLD

                ax.axhline(CMC_THRESHOLD - 0.5, color="black", ls=":", lw=1.0,
                           label=f"decision: >= {CMC_THRESHOLD} cells")
            ax.set_xticks(range(len(labels)))
            ax.set_xticklabels([_tick(m, i) for m, i in labels], fontsize=9)
            ax.set_ylabel(what)
            ax.set_title(f"{fin}: {what} of every pair", fontsize=12)
            ax.grid(True, axis="y", alpha=0.3)
    handles, names = axes[0].get_legend_handles_labels()
    fig.legend(handles, names, loc="outside upper center", ncol=3)
    return fig


def _image(b64):
    import cv2

    buf = np.frombuffer(base64.b64decode(b64), np.uint8)
    return cv2.imdecode(buf, cv2.IMREAD_COLOR)[..., ::-1]


def pair_figure(panels):
    """One same-gun pair: the scans with their cells, a rendered image of the second
    scan, and the recipe's reconstructions with their cells."""
    from psbench.report.figures import new_figure

    a, b = panels["pair"]
    fig, axes = new_figure(ncols=1, nrows=3, w=12.0, h=4.6)
    axes = np.atleast_1d(np.asarray(axes).ravel())
    items = ((panels["scan_cells"], f"scans {a} and {b}: CMC {panels['scan_count']}, "
              f"CCFmax {panels['scan_ccf']:.3f}"),
             (panels["image"], f"{b} rendered ({panels['finish']}, one 62 deg image)"),
             (panels["recipe_cells"], f"recipe ({panels['integrator']}) reconstructions: "
              f"CMC {panels['recipe_count']}, CCFmax {panels['recipe_ccf']:.3f}"))
    for ax, (img, title) in zip(axes, items):
        ax.imshow(_image(img), interpolation="nearest")
        ax.set_xticks([])
        ax.set_yticks([])
        ax.grid(False)
        for s in ax.spines.values():
            s.set_visible(False)
        ax.set_title(title, fontsize=12)
    return fig

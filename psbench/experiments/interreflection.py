"""Beyond the thesis (Section 8.3): what secondary reflections cost, and what SR recovers.

The thesis leaves the light that a concave impression reflects onto itself unsolved and
proposes an iterative ray-tracing normal mask. This experiment renders two concave
surfaces (the ``cup``, a spherical cap, and a ``vgroove``) without and with one bounce of
interreflection (``bounces``), Lambert and Torrance-Sparrow, and solves them with plain
least squares, the thesis's Th-Hi-Re-Sh, two robust solvers (``robust``, ``trim``) and
the SR mask alone, weighted and in Th-Hi-Re-Sh-SR. ``qf_sr`` scores the observations a
solver drops against those whose true secondary fraction exceeds ``t_sr`` (0.5).

The third surface is the firing-pin impression of the synthetic cartridge case (Chapter
7): :func:`prepare` makes the case head at 256 px (39 um a pixel, the coarsest that
holds its features), crops the 48 x 48 px window centred on the impression (a crater
about 37 px across with steep walls, the breech face around it) and saves its heights
(pixel units) as ``<results>/interreflection/firing_pin.npy``; the same file serves
every scale.
"""
from __future__ import annotations

import numpy as np
import pandas as pd

from psbench.report.aggregates import long_frame, lookup, mean
from psbench.report.verdicts import NE_MARGIN, nodata, num, ok, own, verdict

TITLE = "Interreflection: secondary reflections and the SR mask (Section 8.3)"
AVERAGES = ("NE per surface (cup, vgroove, firing_pin: the window of the cartridge "
            "case), model and bounces (0: direct light only; 1: one bounce of "
            "interreflection), 30x8+60x8, cast shadows, 1 % noise; qf_sr on the bounce-1 "
            "scenes; solve time in seconds, mean over the runs of a solver.")
NOTES = ("Not in the thesis (its Section 8.3 names the problem). SR predicts the secondary "
         "light with a Lambertian model from the current normals and subtracts it; it "
         "masks the observations predicted to be mostly secondary light. qf_sr of solvers "
         "without SR shows what they drop for other reasons. SR assumes interreflection: "
         "on scenes rendered without it (bounces 0) it subtracts light that is not there, "
         "and on Torrance-Sparrow images its Lambertian prediction is wrong where the "
         "highlights are; the verdicts below say where that costs more than it gains.")
THESIS: dict = {}
GATED = False

SOLVERS = ("None", "Th-Hi-Re-Sh", "robust", "trim", "SR", "SR weighted", "Th-Hi-Re-Sh-SR")
TABLE_AXES = {"ne lambert": ("solver", "surface / bounces"),
              "ne ts": ("solver", "surface / bounces"),
              "qf_sr": ("solver", "surface / model (bounces 1)"),
              "time": ("solver", "bounces")}
PART_TITLES = {"ne lambert": "NE, Lambert", "ne ts": "NE, Torrance-Sparrow",
               "qf_sr": "QF of the dropped observations against the true secondary "
                        "fraction > 0.5", "time": "Solve time"}


#: side of the firing-pin window (px) and of the cartridge it is cut from
FP_WINDOW, FP_CASE = 48, 256


def firing_pin_path(root):
    """Where :func:`prepare` puts the firing-pin height map."""
    from pathlib import Path

    return Path(root) / "interreflection" / "firing_pin.npy"


def prepare(root, scale=None):
    """Make the firing-pin height map the grid reads, once (atomic write)."""
    from psbench._shared.files import atomic_write
    from psbench.forensic.cartridge import make_cartridge

    out = firing_pin_path(root)
    if out.exists():
        return
    surf = make_cartridge(FP_CASE)
    ys, xs = np.nonzero(surf.regions["firing_pin"])
    cy, cx = int(round(ys.mean())), int(round(xs.mean()))
    h = FP_WINDOW // 2
    y0 = min(max(cy - h, 0), FP_CASE - FP_WINDOW)
    x0 = min(max(cx - h, 0), FP_CASE - FP_WINDOW)
    win = np.ascontiguousarray(surf.height[y0:y0 + FP_WINDOW, x0:x0 + FP_WINDOW], np.float32)
    atomic_write(out, lambda fh: np.save(fh, win - win.max()))


def _surface(s) -> str:
    s = str(s)
    return "firing_pin" if s.endswith("firing_pin.npy") else s


def _solver(r) -> str:
    method = str(r.get("method") or "ps")
    if method not in ("ps", "None", "nan"):
        return method
    mask = str(r.get("mask") or "None")
    return mask + (" weighted" if bool(r.get("weighted")) else "")


def _frame(rows):
    df = rows.copy()
    df["solver"] = [_solver(r) for r in df.to_dict("records")]
    df["surface"] = df["surface"].map(_surface)
    b = pd.to_numeric(df["bounces"], errors="coerce") if "bounces" in df else 0
    df["b"] = pd.Series(b, index=df.index).fillna(0).astype(int)
    return df


def cell_kind(part, column):
    return {"qf_sr": "qf", "time": "time"}.get(part, "ne")


def aggregate(rows):
    """The long-format aggregate of the experiment's ok rows."""
    df = _frame(rows)
    recs = []
    for (model, solver, surf, b), g in df.groupby(["model", "solver", "surface", "b"]):
        v, n = mean(g["ne_mean"])
        if n:
            recs.append((f"ne {model}", solver, f"{surf} {b}", v, n))
        if b > 0 and "qf_sr" in g:
            v, n = mean(g["qf_sr"])
            if n:
                recs.append(("qf_sr", solver, f"{surf} {model}", v, n))
    for (solver, b), g in df.groupby(["solver", "b"]):
        v, n = mean(g["t_solve"])
        if n:
            recs.append(("time", solver, str(b), v, n))
    return long_frame(recs)


def _avg(agg, part, row, cols):
    v = [lookup(agg, part, row, c) for c in cols]
    v = [x for x in v if ok(x)]
    return float(np.mean(v)) if len(v) == len(cols) else float("nan")


def _compare(claim, agg, part, a, b, cols, *, better=True):
    """``a`` beats ``b`` (lower mean NE over ``cols``) when ``better``, else ``a`` is no
    worse than ``b`` by more than the margin."""
    x, y = _avg(agg, part, a, cols), _avg(agg, part, b, cols)
    if not (ok(x) and ok(y)):
        return nodata(claim)
    detail = f"{a} {num(x)} vs {b} {num(y)} deg ({', '.join(cols)})"
    if better:
        return verdict(claim, x < y, detail, undecided=abs(x - y) < NE_MARGIN)
    return verdict(claim, x <= y + NE_MARGIN, detail)


def _best(agg, part, rows, cols):
    vals = {r: _avg(agg, part, r, cols) for r in rows}
    vals = {r: v for r, v in vals.items() if ok(v)}
    return min(vals, key=vals.get) if vals else rows[0]


def verdicts(agg, rows=None):
    """Where SR helps and where it does not, decided on the aggregate (psbench's own
    questions, shown apart from the thesis's conclusions)."""
    b1 = ["cup 1", "vgroove 1"]
    b0 = ["cup 0", "vgroove 0"]
    out = [
        _compare("On Lambertian concave surfaces with one bounce, SR beats plain least "
                 "squares", agg, "ne lambert", "SR", "None", b1),
        _compare("...and beats the better robust solver (robust, trim)", agg, "ne lambert",
                 "SR", _best(agg, "ne lambert", ("robust", "trim"), b1), b1),
        _compare("Th-Hi-Re-Sh-SR beats Th-Hi-Re-Sh under interreflection (Lambert)", agg,
                 "ne lambert", "Th-Hi-Re-Sh-SR", "Th-Hi-Re-Sh", b1),
        _compare("Th-Hi-Re-Sh-SR beats Th-Hi-Re-Sh under interreflection (TS)", agg,
                 "ne ts", "Th-Hi-Re-Sh-SR", "Th-Hi-Re-Sh", b1),
        _compare("On TS images with one bounce SR alone beats plain least squares", agg,
                 "ne ts", "SR", "None", b1),
        _compare("Without interreflection SR costs nothing against plain least squares "
                 "(Lambert)", agg, "ne lambert", "SR", "None", b0, better=False),
        _compare("Without interreflection Th-Hi-Re-Sh-SR costs nothing against Th-Hi-Re-Sh "
                 "(TS)", agg, "ne ts", "Th-Hi-Re-Sh-SR", "Th-Hi-Re-Sh", b0, better=False),
        _compare("The weighted form of SR is no worse than the binary one (Lambert, bounce "
                 "1)", agg, "ne lambert", "SR weighted", "SR", b1, better=False),
    ]
    fp = ["firing_pin 1"]
    out += [
        _compare("On the firing-pin impression with one bounce, SR beats plain least squares "
                 "(Lambert)", agg, "ne lambert", "SR", "None", fp),
        _compare("On the firing-pin impression with one bounce, Th-Hi-Re-Sh-SR beats "
                 "Th-Hi-Re-Sh (TS)", agg, "ne ts", "Th-Hi-Re-Sh-SR", "Th-Hi-Re-Sh", fp),
    ]
    all1 = ["cup 1", "vgroove 1", "firing_pin 1"]
    sr = _best(agg, "ne ts", ("SR", "SR weighted", "Th-Hi-Re-Sh-SR"), all1)
    out.append(_compare("On TS images with one bounce, the best SR combination beats the "
                        "better robust solver", agg, "ne ts", sr,
                        _best(agg, "ne ts", ("robust", "trim"), all1), all1))
    q = [lookup(agg, "qf_sr", "SR", c) for c in ("cup lambert", "vgroove lambert")]
    if all(ok(x) for x in q):
        out.append(verdict("SR drops the observations that are mostly secondary light "
                           "(QF > 0.5 on the Lambert scenes)", min(q) > 0.5,
                           "qf_sr " + ", ".join(num(x) for x in q)))
    else:
        out.append(nodata("SR drops the observations that are mostly secondary light"))
    return [own(v) for v in out]  # psbench's own questions: the thesis has no numbers


def figures(agg):
    from psbench.report.figures import finish, new_figure

    out = []
    for model in ("lambert", "ts"):
        part = f"ne {model}"
        if agg is None or agg.empty or not (agg["part"] == part).any():
            continue
        cols = sorted(agg.loc[agg["part"] == part, "column"].unique())
        fig, (ax,) = new_figure()
        width = 0.8 / len(SOLVERS)
        x = np.arange(len(cols))
        for i, s in enumerate(SOLVERS):
            ax.bar(x + (i - len(SOLVERS) / 2 + 0.5) * width,
                   [lookup(agg, part, s, c) for c in cols], width, label=s)
        ax.set_xticks(x, cols)
        ax.legend(fontsize="small", ncol=2)
        finish(ax, "surface and bounces", "NE (deg)")
        out.append((f"interreflection_{model}", fig))
    return out

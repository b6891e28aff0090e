"""Render report pages to Markdown and HTML from one list of blocks; atomic file writes.

A page is a list of blocks:

- ``("h1"|"h2"|"h3", text)``, ``("p", text)``, ``("list", [text, ...])``;
- ``("table", DataFrame[, caption])``: cells are shown as they are (format numbers
  before); two-level column labels (a ``MultiIndex``) become a grouped header in HTML
  and ``"group: sub"`` headers in Markdown; a :class:`Link` cell is a link; a cell
  holding a verdict status is coloured;
- ``("img", relpath, caption)``, ``("pre", text)``, ``("links", [(href, text), ...])``;
- ``("verdicts", [Verdict, ...])``: one table row per verdict (status, claim, numbers);
  ``("own_verdicts", [...])`` the same for psbench's own questions (row class
  ``verdict own``, not counted as thesis verdicts);
- ``("totals", {"SUPPORTED": n, "NOT SUPPORTED": n, "INCONCLUSIVE": n})``: the verdict
  totals as three badges.

Text may use inline Markdown (```code```, ``**bold**``, ``[text](href)``): the Markdown
page keeps it, the HTML page renders it (:func:`inline_html`), so no raw Markdown is left
in the HTML.
"""
from __future__ import annotations

import html as _html
import re
from dataclasses import dataclass
from pathlib import Path

import pandas as pd

__all__ = ["Link", "STATUSES", "write_atomic", "save_figure", "inline_html", "to_markdown",
           "to_html", "write_page"]

#: verdict statuses; PROVISIONAL: decided on an incomplete grid (shown only when present)
STATUSES = ("SUPPORTED", "NOT SUPPORTED", "INCONCLUSIVE", "PROVISIONAL")
_STATUS_CLASS = {"SUPPORTED": "st-s", "NOT SUPPORTED": "st-n", "INCONCLUSIVE": "st-i",
                 "PROVISIONAL": "st-p"}

_CSS = """
body{font-family:system-ui,-apple-system,"Segoe UI",Roboto,sans-serif;font-size:15px;
 line-height:1.45;max-width:1200px;margin:1.2em auto;padding:0 1.2em;color:#1d1d1d}
h1{font-size:1.6em;margin:.4em 0 .5em}h2{font-size:1.3em;margin-top:1.6em;
 border-bottom:1px solid #ddd;padding-bottom:.2em}h3{font-size:1.08em;margin-top:1.2em}
code{font-family:ui-monospace,Menlo,Consolas,monospace;font-size:.92em;background:#f1f3f5;
 padding:.05em .3em;border-radius:3px}
pre{background:#f6f8fa;border:1px solid #e3e6e8;padding:.6em .8em;overflow-x:auto;
 font-size:13px;line-height:1.35}
table{border-collapse:collapse;font-size:13.5px;margin:.6em 0 1em;
 font-variant-numeric:tabular-nums}
p.cap{font-size:13px;color:#555;margin:.6em 0 .1em}th.wide{min-width:22em}
td,th{border:1px solid #d4d7da;padding:3px 8px;text-align:left;vertical-align:top}
th{background:#eef1f4;font-weight:600}thead tr:first-child th{background:#e2e7ec}
td.num,th.num{text-align:right}th[colspan]{text-align:center}
tbody td:first-child{white-space:nowrap}
tbody tr:nth-child(even){background:#fafbfc}
.st-s{color:#0a6b1f;font-weight:700}.st-n{color:#b3001b;font-weight:700}
.st-i{color:#8a5a00;font-weight:700}.st-p{color:#5a5a8a;font-weight:700}
td.st-s,td.st-n,td.st-i,td.st-p{white-space:nowrap;text-align:left}
.totals{display:flex;gap:.8em;flex-wrap:wrap;margin:.6em 0 1em}
.badge{border-radius:6px;padding:.45em .9em;font-size:1.15em;font-weight:700;color:#fff}
.badge .n{font-size:1.5em;margin-right:.3em}
.badge.st-s{background:#1e7b34}.badge.st-n{background:#b3261e}.badge.st-i{background:#9a6a00}
.badge.st-p{background:#5a5a8a}
.badge.all{background:#44505c}
figure{margin:1em 0}img{max-width:100%;height:auto;border:1px solid #e1e4e8}
figcaption{font-size:13px;color:#555;margin-top:.3em}
table.verdicts td:nth-child(2),table.verdicts td:nth-child(3){text-align:left}
table.verdicts td:nth-child(3){color:#444;font-size:13px}
.quote{color:#555;font-style:italic;font-size:13px;margin-top:.3em}
"""


@dataclass(frozen=True)
class Link:
    """A table cell that links ``href`` with the label ``text``."""

    text: str
    href: str

    def __str__(self):
        return self.text


def write_atomic(path, data) -> Path:
    """Write text or bytes to ``path`` atomically (:func:`psbench._shared.files.atomic_write`)."""
    from psbench._shared.files import atomic_write

    return atomic_write(path, data, fsync=False)


def save_figure(fig, path, dpi=100, palette=False) -> Path:
    """Save a matplotlib figure as PNG atomically and close it.

    ``palette=True`` stores a 256-colour palette PNG (much smaller for image panels).
    """
    import io

    import matplotlib.pyplot as plt

    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=dpi, bbox_inches="tight", facecolor="white")
    plt.close(fig)
    data = buf.getvalue()
    if palette:
        try:
            from PIL import Image

            img = Image.open(io.BytesIO(data)).convert("RGB").quantize(colors=256)
            out = io.BytesIO()
            img.save(out, format="PNG", optimize=True)
            data = out.getvalue()
        except Exception:  # noqa: BLE001 - keep the full-colour PNG
            pass
    return write_atomic(path, data)


# ----------------------------------------------------------------------------- inline text

_CODE = re.compile(r"`([^`]+)`")
_BOLD = re.compile(r"\*\*(.+?)\*\*")
_LINK = re.compile(r"\[([^\]]+)\]\(([^)\s]+)\)")


def inline_html(text) -> str:
    """HTML of one line of text with inline Markdown: ```code```, ``**bold**``,
    ``[text](href)``; everything else is escaped."""
    parts = _CODE.split(str(text))
    out = []
    for i, part in enumerate(parts):
        if i % 2:
            out.append(f"<code>{_html.escape(part)}</code>")
            continue
        s = _html.escape(part)
        s = _BOLD.sub(r"<strong>\1</strong>", s)
        s = _LINK.sub(r'<a href="\2">\1</a>', s)
        out.append(s)
    return "".join(out)


def _status_class(text: str) -> str | None:
    return _STATUS_CLASS.get(str(text).strip())


# ----------------------------------------------------------------------------- tables

def _cell_text(v) -> str:
    if v is None:
        return ""
    if isinstance(v, float):
        if v != v:
            return ""
        return f"{v:.4g}" if abs(v) < 1e4 else f"{v:.3e}"
    return str(v)


def _columns(df) -> list[tuple[str, str]]:
    """``(group, sub)`` per column; ``group`` is "" for single-level labels."""
    if isinstance(df.columns, pd.MultiIndex):
        return [(str(a), str(b)) for a, b in df.columns]
    return [("", str(c)) for c in df.columns]


def _md_cell(v) -> str:
    if isinstance(v, Link):
        return f"[{v.text}]({v.href})"
    return _cell_text(v).replace("|", "\\|").replace("\n", " ")


def _md_table(df: pd.DataFrame, caption=None) -> str:
    if df is None or df.empty:
        return "_(no rows)_\n"
    heads = [f"{g}: {s}" if g and s else (g or s) for g, s in _columns(df)]
    lines = ([f"_{caption}_", ""] if caption else []) + \
        ["| " + " | ".join(heads) + " |", "|" + "|".join("---" for _ in heads) + "|"]
    for row in df.itertuples(index=False):
        lines.append("| " + " | ".join(_md_cell(v) for v in row) + " |")
    return "\n".join(lines) + "\n"


def _html_cell(v, numeric=False) -> str:
    if isinstance(v, Link):
        return f"<td><a href=\"{_html.escape(v.href)}\">{_html.escape(v.text)}</a></td>"
    text = _cell_text(v)
    cls = _status_class(text)
    if cls:
        return f"<td class='{cls}'>{_html.escape(text)}</td>"
    return f"<td class='num'>{inline_html(text)}</td>" if numeric else \
        f"<td>{inline_html(text)}</td>"


def _looks_numeric(text: str) -> bool:
    return bool(re.fullmatch(r"[-+]?[\d.,]+(e[-+]?\d+)?\s*[%x]?|—|n/a", text.strip()))


def _numeric_columns(df) -> list[bool]:
    """Columns whose every non-empty cell is a number (right-aligned)."""
    out = []
    for j in range(df.shape[1]):
        col = list(df.iloc[:, j])
        texts = [_cell_text(v) for v in col if not isinstance(v, Link)]
        out.append(len(texts) == len(col) and any(texts)
                   and all(_looks_numeric(t) for t in texts if t))
    return out


#: headers of long-text columns, kept wide enough to read
_WIDE = {"claim", "claim (thesis)", "deviation", "error"}


def _th(text, numeric, extra=""):
    cls = " class='num'" if numeric else " class='wide'" if str(text) in _WIDE else ""
    return f"<th{cls}{extra}>{inline_html(text)}</th>"


def _html_head(df, numeric) -> str:
    cols = _columns(df)
    if not any(g for g, _ in cols):
        return "<tr>" + "".join(_th(s, n) for (_, s), n in zip(cols, numeric)) + "</tr>"
    top, sub = [], []
    i = 0
    while i < len(cols):
        g = cols[i][0]
        j = i
        while j < len(cols) and cols[j][0] == g:
            j += 1
        if not g or (j - i == 1 and not cols[i][1]):
            top.append(_th(cols[i][1] or g, numeric[i], " rowspan='2'"))
            i += 1
            continue
        top.append(_th(g, False, f" colspan='{j - i}'"))
        sub += [_th(s, n) for (_, s), n in zip(cols[i:j], numeric[i:j])]
        i = j
    return f"<tr>{''.join(top)}</tr><tr>{''.join(sub)}</tr>"


def _html_table(df: pd.DataFrame, caption=None, cls=None) -> str:
    if df is None or df.empty:
        return "<p><em>(no rows)</em></p>"
    cap = f"<p class='cap'>{inline_html(caption)}</p>" if caption else ""
    numeric = _numeric_columns(df)
    body = "".join("<tr>" + "".join(_html_cell(v, n) for v, n in zip(row, numeric)) + "</tr>"
                   for row in df.itertuples(index=False))
    c = f" class='{cls}'" if cls else ""
    return (f"{cap}<table{c}><thead>{_html_head(df, numeric)}</thead><tbody>{body}</tbody>"
            f"</table>")


def _claim_md(v) -> str:
    return v.claim + (f" (thesis, {v.quote})" if getattr(v, "quote", "") else "")


def _verdict_frame(vs) -> pd.DataFrame:
    return pd.DataFrame([{"status": v.status, "claim": _claim_md(v),
                          "psbench's numbers": v.detail}
                         for v in vs], columns=["status", "claim", "psbench's numbers"])


def _shown(t: dict) -> list:
    """Statuses of a totals line: the three decided ones always, PROVISIONAL when held."""
    return [s for s in STATUSES if s != "PROVISIONAL" or t.get(s, 0)]


def _totals_md(t: dict) -> str:
    n = sum(t.get(s, 0) for s in STATUSES)
    return (f"**{n} claim{'' if n == 1 else 's'}: "
            + " · ".join(f"{t.get(s, 0)} {s}" for s in _shown(t)) + "**\n")


def _totals_html(t: dict) -> str:
    n = sum(t.get(s, 0) for s in STATUSES)
    badges = [f"<div class='badge all'><span class='n'>{n}</span>claim{'' if n == 1 else 's'}"
              f"</div>"]
    badges += [f"<div class='badge {_STATUS_CLASS[s]}' data-status='{s}'><span class='n'>"
               f"{t.get(s, 0)}</span>{s}</div>" for s in _shown(t)]
    return f"<div class='totals'>{''.join(badges)}</div>"


# ----------------------------------------------------------------------------- pages

def to_markdown(blocks) -> str:
    """The Markdown page of ``blocks``."""
    out = []
    for b in blocks:
        k = b[0]
        if k in ("h1", "h2", "h3"):
            out.append("#" * int(k[1]) + " " + b[1] + "\n")
        elif k == "p":
            out.append(b[1] + "\n")
        elif k == "list":
            out.append("\n".join(f"- {x}" for x in b[1]) + "\n")
        elif k == "table":
            out.append(_md_table(b[1], b[2] if len(b) > 2 else None))
        elif k == "img":
            out.append(f"![{b[2]}]({b[1]})\n\n_{b[2]}_\n")
        elif k in ("verdicts", "own_verdicts"):
            out.append(_md_table(_verdict_frame(b[1])) if b[1] else "_(no verdicts)_\n")
        elif k == "totals":
            out.append(_totals_md(b[1]))
        elif k == "pre":
            out.append("```\n" + b[1] + "\n```\n")
        elif k == "links":
            out.append("\n".join(f"- [{t}]({h})" for h, t in b[1]) + "\n")
    return "\n".join(out)


def to_html(blocks, title) -> str:
    """The HTML page of ``blocks`` (self-contained: inline CSS, relative image links)."""
    e = _html.escape
    out = [f"<!DOCTYPE html><html lang='en'><head><meta charset='utf-8'>"
           f"<meta name='viewport' content='width=device-width,initial-scale=1'>"
           f"<title>{e(title)}</title><style>{_CSS}</style></head><body>"]
    for b in blocks:
        k = b[0]
        if k in ("h1", "h2", "h3"):
            out.append(f"<{k}>{inline_html(b[1])}</{k}>")
        elif k == "p":
            out.append(f"<p>{inline_html(b[1])}</p>")
        elif k == "list":
            out.append("<ul>" + "".join(f"<li>{inline_html(x)}</li>" for x in b[1]) + "</ul>")
        elif k == "table":
            out.append(_html_table(b[1], b[2] if len(b) > 2 else None))
        elif k == "img":
            out.append(f"<figure><img src='{e(b[1])}' alt='{e(b[2])}'>"
                       f"<figcaption>{inline_html(b[2])}</figcaption></figure>")
        elif k in ("verdicts", "own_verdicts"):
            cls = "verdict" if k == "verdicts" else "verdict own"
            out.append(_verdicts_html(b[1], cls) if b[1] else "<p><em>(no verdicts)</em></p>")
        elif k == "totals":
            out.append(_totals_html(b[1]))
        elif k == "pre":
            out.append(f"<pre>{e(b[1])}</pre>")
        elif k == "links":
            out.append("<ul>" + "".join(f"<li><a href='{e(h)}'>{inline_html(t)}</a></li>"
                                        for h, t in b[1]) + "</ul>")
    out.append("</body></html>")
    return "\n".join(out)


def _quote_html(v) -> str:
    q = getattr(v, "quote", "")
    return f"<div class='quote'>thesis, {_html.escape(q)}</div>" if q else ""


def _verdicts_html(vs, cls="verdict") -> str:
    head = "claim (thesis)" if cls == "verdict" else "question (psbench)"
    rows = "".join(
        f"<tr class='{cls}'><td class='{_STATUS_CLASS.get(v.status, '')}'>"
        f"{_html.escape(v.status)}</td><td>{inline_html(v.claim)}{_quote_html(v)}</td>"
        f"<td>{inline_html(v.detail)}</td></tr>" for v in vs)
    return ("<table class='verdicts'><thead><tr><th>status</th>"
            f"<th class='wide'>{head}</th><th>psbench's numbers</th></tr></thead>"
            f"<tbody>{rows}</tbody></table>")


def write_page(out_dir, stem, blocks, title):
    """Write ``<stem>.md`` and ``<stem>.html`` atomically; returns both paths."""
    out_dir = Path(out_dir)
    md = write_atomic(out_dir / f"{stem}.md", to_markdown(blocks))
    ht = write_atomic(out_dir / f"{stem}.html", to_html(blocks, title))
    return md, ht

"""Render report pages to Markdown and HTML from one list of blocks; atomic file writes.

A page is a list of blocks: ``("h1"|"h2"|"h3", text)``, ``("p", text)``,
``("list", [text, ...])``, ``("table", DataFrame)``, ``("img", relpath, caption)``,
``("verdicts", [Verdict, ...])``, ``("pre", text)``, ``("links", [(href, text), ...])``.
"""
from __future__ import annotations

import html as _html
from pathlib import Path

import pandas as pd

_CSS = """body{font-family:sans-serif;max-width:1100px;margin:1em auto;padding:0 1em;color:#222}
table{border-collapse:collapse;font-size:12px;margin:.5em 0}
td,th{border:1px solid #ccc;padding:2px 6px;text-align:right}
th{background:#f0f0f0} td:first-child,th:first-child{text-align:left}
.SUPPORTED{color:#080;font-weight:bold}.NOT{color:#b00;font-weight:bold}
.INCONCLUSIVE{color:#a60;font-weight:bold} img{max-width:100%;border:1px solid #ddd}
pre{background:#f6f6f6;padding:.5em;overflow-x:auto;font-size:12px} .small{font-size:12px;color:#555}
"""


def write_atomic(path, data) -> Path:
    """Write text or bytes to ``path`` atomically (:func:`psbench._fs.atomic_write`)."""
    from psbench._fs import atomic_write

    return atomic_write(path, data, fsync=False)


def save_figure(fig, path, dpi=80, palette=False) -> Path:
    """Save a matplotlib figure as PNG atomically and close it.

    ``palette=True`` stores a 256-colour palette PNG (much smaller for image panels).
    """
    import io

    import matplotlib.pyplot as plt

    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=dpi, bbox_inches="tight")
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


def _cell(v) -> str:
    if v is None:
        return ""
    if isinstance(v, float):
        if v != v:
            return ""
        return f"{v:.4g}" if abs(v) < 1e4 else f"{v:.3e}"
    return str(v)


def _md_table(df: pd.DataFrame) -> str:
    if df is None or df.empty:
        return "_(no rows)_\n"
    cols = [str(c) for c in df.columns]
    lines = ["| " + " | ".join(cols) + " |", "|" + "|".join("---" for _ in cols) + "|"]
    for row in df.itertuples(index=False):
        lines.append("| " + " | ".join(_cell(v).replace("|", "\\|") for v in row) + " |")
    return "\n".join(lines) + "\n"


def _html_table(df: pd.DataFrame) -> str:
    if df is None or df.empty:
        return "<p><em>(no rows)</em></p>"
    head = "".join(f"<th>{_html.escape(str(c))}</th>" for c in df.columns)
    body = "".join("<tr>" + "".join(f"<td>{_html.escape(_cell(v))}</td>" for v in row) + "</tr>"
                   for row in df.itertuples(index=False))
    return f"<table><thead><tr>{head}</tr></thead><tbody>{body}</tbody></table>"


def to_markdown(blocks) -> str:
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
            out.append(_md_table(b[1]))
        elif k == "img":
            out.append(f"![{b[2]}]({b[1]})\n\n_{b[2]}_\n")
        elif k == "verdicts":
            out.append("\n".join(f"- **{v.status}** — {v.claim}: {v.detail}" for v in b[1])
                       + "\n" if b[1] else "_(no verdicts)_\n")
        elif k == "pre":
            out.append("```\n" + b[1] + "\n```\n")
        elif k == "links":
            out.append("\n".join(f"- [{t}]({h})" for h, t in b[1]) + "\n")
    return "\n".join(out)


def to_html(blocks, title) -> str:
    e = _html.escape
    out = [f"<!DOCTYPE html><html><head><meta charset='utf-8'><title>{e(title)}</title>"
           f"<style>{_CSS}</style></head><body>"]
    for b in blocks:
        k = b[0]
        if k in ("h1", "h2", "h3"):
            out.append(f"<{k}>{e(b[1])}</{k}>")
        elif k == "p":
            out.append(f"<p>{e(b[1])}</p>")
        elif k == "list":
            out.append("<ul>" + "".join(f"<li>{e(x)}</li>" for x in b[1]) + "</ul>")
        elif k == "table":
            out.append(_html_table(b[1]))
        elif k == "img":
            out.append(f"<figure><img src='{e(b[1])}' alt='{e(b[2])}'>"
                       f"<figcaption class='small'>{e(b[2])}</figcaption></figure>")
        elif k == "verdicts":
            items = "".join(
                f"<li><span class='{e(v.status.split()[0])}'>{e(v.status)}</span> — "
                f"{e(v.claim)}: <span class='small'>{e(v.detail)}</span></li>" for v in b[1])
            out.append(f"<ul>{items}</ul>" if b[1] else "<p><em>(no verdicts)</em></p>")
        elif k == "pre":
            out.append(f"<pre>{e(b[1])}</pre>")
        elif k == "links":
            out.append("<ul>" + "".join(f"<li><a href='{e(h)}'>{e(t)}</a></li>" for h, t in b[1])
                       + "</ul>")
    out.append("</body></html>")
    return "\n".join(out)


def write_page(out_dir, stem, blocks, title):
    """Write ``<stem>.md`` and ``<stem>.html`` atomically; returns both paths."""
    out_dir = Path(out_dir)
    md = write_atomic(out_dir / f"{stem}.md", to_markdown(blocks))
    ht = write_atomic(out_dir / f"{stem}.html", to_html(blocks, title))
    return md, ht

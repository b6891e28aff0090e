"""The report pages as a reader sees them: images, rendered Markdown, verdict totals."""
from __future__ import annotations

import json
import re
import shutil
import struct

import pandas as pd
import pytest
from test_report import _store, row, table5_3_rows

from psbench.report import tables as T
from psbench.report.cli import build
from psbench.io.html import Link, inline_html, to_html, to_markdown
from psbench.report.present import fmt
from psbench.report.verdicts import INCONCLUSIVE, NOT_SUPPORTED, SUPPORTED, Verdict

NAMES = ["table2_1", "table5_3", "table6_2", "fig4_9", "fig5_12", "interpretations"]
STATUSES = (SUPPORTED, NOT_SUPPORTED, INCONCLUSIVE)


@pytest.fixture(scope="module")
def report(tmp_path_factory, small_panels):
    """A full-scale report of a few experiments (one with a failed run, one without data)
    and the image panels at a small size."""
    tmp = tmp_path_factory.mktemp("pages")
    rows = table5_3_rows(size=512)
    rows += [row("fig5_12", 1000 + i, surface=s, lights="45x8", n_images=8, noise=nz, size=512,
                 mask=m, ne_mean=5 + 10 * nz + (3 * nz if m == "RA" else 0))
             for i, (s, nz, m) in enumerate((s, nz, m) for s in ("semisphere", "penny")
                                            for nz in (0.0, 0.1, 0.2)
                                            for m in ("None", "Th", "RA"))]
    rows.append(row("table6_2", 5000, data="/x/diligent/cat", lights="30x4+60x4",
                    status="failed", error="PsbenchError: data='/x/diligent/cat' not found"))
    out = tmp / "reports"
    shutil.copytree(small_panels[0], out)       # panels.build_panels(out, size=24)
    mp = pytest.MonkeyPatch()
    mp.setattr(T, "names", lambda: list(NAMES))
    try:
        build(_store(tmp, rows), out, "full", log=lambda *a: None)
    finally:
        mp.undo()
    return out


def _pages(out):
    return sorted(out.glob("*.html"))


def _png_size(path):
    head = path.read_bytes()[:24]
    assert head[:8] == b"\x89PNG\r\n\x1a\n", path
    return struct.unpack(">II", head[16:24])


def _visible(html):
    """HTML without its <pre> blocks (verbatim YAML) and tags."""
    html = re.sub(r"<pre>.*?</pre>", "", html, flags=re.S)
    html = re.sub(r"<style>.*?</style>", "", html, flags=re.S)
    return re.sub(r"<[^>]+>", " ", html)


def test_every_page_is_written(report):
    stems = {p.stem for p in _pages(report)}
    assert stems == set(NAMES) | {"index", "panels"}
    for stem in stems:
        assert (report / f"{stem}.md").is_file()


def test_every_image_of_every_page_exists_and_figures_are_wide(report):
    n = 0
    for page in _pages(report):
        for src in re.findall(r"<img src='([^']+)'", page.read_text()):
            path = report / src
            assert path.is_file(), (page.name, src)
            w, h = _png_size(path)
            assert w >= 900, (src, w)          # readable at page width
            n += 1
    assert n >= 3 + 5                          # table5_3 (2), fig5_12 and the five panels


def test_no_raw_markdown_in_html(report):
    for page in _pages(report):
        text = _visible(page.read_text())
        assert "`" not in text, page.name
        assert "**" not in text, page.name
        assert "|---" not in text and "| ---" not in text, page.name
        assert not re.search(r"\]\([^)]*\)", text), page.name
        assert not re.search(r"^\s*#+ ", text, flags=re.M), page.name
    # inline code is rendered as code
    assert "<code>psbench +experiment=fig4_9 scale=full</code>" in \
        (report / "fig4_9.html").read_text()


def _page_tally(html):
    return {s: len(re.findall(rf"<tr class='verdict'><td class='[^']*'>{s}</td>", html))
            for s in STATUSES}


def _badges(html):
    return {s: int(re.search(rf"data-status='{s}'><span class='n'>(\d+)</span>", html).group(1))
            for s in STATUSES}


def test_verdict_totals_on_the_index_equal_the_verdict_lines_of_the_pages(report):
    pages = {p.stem: _page_tally(p.read_text()) for p in _pages(report)
             if p.stem not in ("index", "panels")}
    # the matrix of readings re-decides other pages' claims: on its page, not in the totals
    assert sum(pages["interpretations"].values()) >= 1
    total = {s: sum(t[s] for n, t in pages.items() if n != "interpretations")
             for s in STATUSES}
    assert sum(total.values()) > 10
    index = (report / "index.html").read_text()
    assert _badges(index) == total
    # the totals open the index (before the key findings and the rest)
    assert index.index("class='totals'") < index.index("Key findings")
    md = (report / "index.md").read_text()
    assert f"{sum(total.values())} claims: {total[SUPPORTED]} SUPPORTED · " \
           f"{total[NOT_SUPPORTED]} NOT SUPPORTED · {total[INCONCLUSIVE]} INCONCLUSIVE" in md
    # each page's own badges and report.json agree with its lines
    man = json.loads((report / "report.json").read_text())
    assert man["scale"] == "full" and man["verdicts"] == total
    assert "interpretations" not in man["in_totals"] and "table5_3" in man["in_totals"]
    for name, tally in pages.items():
        assert _badges((report / f"{name}.html").read_text()) == tally
        assert {s: man["experiments"][name][s] for s in STATUSES} == tally


def test_key_findings_are_the_first_claim_of_each_experiment(report):
    md = (report / "index.md").read_text()
    findings = md.split("## Key findings")[1].split("\n## ")[0]
    lines = [ln for ln in findings.splitlines() if ln.startswith("| ") and "---" not in ln][1:]
    assert len(lines) == len(NAMES)
    statuses = [ln.split(" | ")[0].strip("| ") for ln in lines]
    order = {NOT_SUPPORTED: 0, SUPPORTED: 1, INCONCLUSIVE: 2}
    assert [order[s] for s in statuses] == sorted(order[s] for s in statuses)
    assert "Th-Hi-Re-Sh has the lowest NE (all light sources)" in findings


def test_panel_values_are_tables_with_units(report):
    md = (report / "panels.md").read_text()
    assert "| mask | semisphere | sombrero | penny | mozart |" in md
    assert "values: mean NE over the object in deg" in md
    assert not re.search(r"^- .*mean NE", md, flags=re.M)           # no bullet list


def test_comparison_columns_units_and_time_ratios(report):
    html = (report / "table5_3.html").read_text()
    assert "<th colspan='3'>NE (deg)</th>" in html
    assert "<th class='num'>thesis (x None)</th>" in html
    md = (report / "table5_3.md").read_text()
    assert "time: psbench (s)" in md and "time: thesis (x None)" in md
    assert not re.search(r"\d / \d", md.split("## psbench vs thesis")[1].split("## What")[0])
    failed = (report / "table6_2.md").read_text()
    assert "| runs | error |" in failed and "not found" in failed


def test_html_blocks_render_inline_markdown_and_grouped_headers():
    assert inline_html("run `a<b` **now** [x](y.html)") == \
        "run <code>a&lt;b</code> <strong>now</strong> <a href=\"y.html\">x</a>"
    df = pd.DataFrame([["Th", "8.38", "8.28", "+0.10", Link("p", "p.html")]],
                      columns=pd.MultiIndex.from_tuples([("", "mask"), ("NE (deg)", "psbench"),
                                                         ("NE (deg)", "thesis"),
                                                         ("NE (deg)", "Δ"), ("", "page")]))
    v = Verdict("e", "claim `x`", NOT_SUPPORTED, "1 vs 2")
    blocks = [("h1", "T"), ("table", df, "rows: mask"), ("verdicts", [v]),
              ("totals", {SUPPORTED: 0, NOT_SUPPORTED: 1, INCONCLUSIVE: 0})]
    html = to_html(blocks, "T")
    assert "<th rowspan='2'>mask</th><th colspan='3'>NE (deg)</th>" in html
    assert "<td class='num'>+0.10</td>" in html and "<a href=\"p.html\">p</a>" in html
    assert "<tr class='verdict'><td class='st-n'>NOT SUPPORTED</td><td>claim <code>x</code>" \
        in html
    md = to_markdown(blocks)
    assert "| mask | NE (deg): psbench | NE (deg): thesis | NE (deg): Δ | page |" in md
    assert "| Th | 8.38 | 8.28 | +0.10 | [p](p.html) |" in md
    assert "**1 claim: 0 SUPPORTED · 1 NOT SUPPORTED · 0 INCONCLUSIVE**" in md


def test_number_format_is_consistent():
    assert fmt(8.375, 2) == "8.38" and fmt(-0.001, 2) == "0.00"
    assert fmt(-0.001, 2, sign=True) == "+0.00" and fmt(0.1, 2, sign=True) == "+0.10"
    assert fmt(float("nan"), 2) == "—" and fmt(None, 1) == "—"
    assert fmt(0.35, "exact") == "0.35" and fmt(40.0, "exact") == "40"
    assert fmt(-0.1, "exact", sign=True) == "-0.1"


def test_a_verdict_shows_the_thesis_sentence_it_tests(report):
    html = (report / "table5_3.html").read_text()
    quotes = re.findall(r"<div class='quote'>thesis, (.+?)</div>", html)
    assert quotes and all(len(q) > 10 for q in quotes)
    assert "(thesis, line " in (report / "table5_3.md").read_text()


def test_psbench_own_questions_are_shown_apart_and_not_counted(report):
    html = (report / "table5_3.html").read_text()
    own = re.findall(r"<tr class='verdict own'>", html)
    assert len(own) == 3                              # tsfit vs masks, per noise level
    assert html.index("own questions</h2>") > html.index("class='totals'")
    man = json.loads((report / "report.json").read_text())
    assert sum(man["experiments"]["table5_3"][s] for s in STATUSES) == \
        sum(_page_tally(html).values())


def test_parameter_lists_do_not_follow_the_store_order():
    """A page's parameter table lists values in one order, whatever order the store
    returned the rows in (a reproduction must give the same page)."""
    import pandas as pd

    from psbench.report.pages import _parameters

    rows = pd.DataFrame({"lights": ["45x8", "30x8", "60x8", "30x8"], "noise": [0.1, 0.0, 0.2, 0.0]})
    a = _parameters(rows).to_dict("records")
    b = _parameters(rows.iloc[::-1]).to_dict("records")
    assert a == b
    assert a[0] == {"parameter": "lights", "values": "30x8, 45x8, 60x8"}
    assert a[1] == {"parameter": "noise", "values": "0, 0.1, 0.2"}


def test_analysis_runs_list_their_own_settings_not_the_scene_defaults():
    """An analysis run's parameter table shows what it received (the settings its function
    names, its args and its study), not the scene and solver defaults it never used, and
    leaves out the settings that only say how it was computed."""
    import json

    import pandas as pd

    from psbench.report.pages import _parameters

    rows = pd.DataFrame({
        "kind": ["analysis"] * 2, "analysis": ["breechface"] * 2, "surface": ["sombrero2"] * 2,
        "mask": ["Th"] * 2, "size": [512] * 2, "seed": [0, 1],
        "args": [json.dumps({"label": "None", "finish": "brass"}),
                 json.dumps({"label": "recipe", "finish": "brass"})],
        "study": [json.dumps({"folder": "scans", "finishes": ["brass"],
                              "cache": "results/cache"})] * 2})
    table = dict(_parameters(rows).itertuples(index=False))
    assert table == {"analysis": "breechface", "seed": "0, 1", "label": "None, recipe",
                     "finish": "brass", "study.folder": "scans",
                     "study.finishes": '["brass"]'}

"""The documentation shows no printed output typed by hand, so none can go stale.

Printed rows, sweep tables and pictures in docs/ come from the build-time directives
``psbench-run`` / ``psbench-python`` (docs/_ext/psbench_run.py) and the executed gallery:
the build prints what psbench prints that day and fails when a command fails. These
tests (a fraction of a second, no build) check the rest: that every other code block of
the README and the pages is input only (commands, code, configuration, formulas), that
the few psbench messages quoted in the prose are messages psbench still prints, that the
set-up commands agree between the README, the pages and CI, and that the store's column
table names every column of the schema.
"""
from __future__ import annotations

import ast
import re
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
DOCS = ROOT / "docs"
PAGES = [ROOT / "README.md", *sorted(DOCS.glob("*.md")), *sorted((DOCS / "guide").glob("*.md"))]
FENCE = re.compile(r"^(`{3,})([^\n`]*)\n(.*?)^\1\s*$", re.S | re.M)
#: what a line of a ``bash`` block may start with: a program or an environment assignment
COMMANDS = re.compile(r"(psbench(-\w+)?|python3?|\.venv/bin/\S+|sudo|pip|git|cd|export|bash|"
                      r"benchmarks/\S+|ln|eval|sbatch|srun|[A-Z_]+=\S*)(\s|$)")
#: block languages that hold input only; a psbench directive's output is produced at build
INPUT = {"bash", "python", "toml", "yaml", "text"}
DIRECTIVES = {"{psbench-run}", "{psbench-python}", "{toctree}"}


def _blocks():
    for page in PAGES:
        for m in FENCE.finditer(page.read_text()):
            yield page.relative_to(ROOT).as_posix(), m.group(2).strip(), m.group(3)


BLOCKS = list(_blocks())


def test_the_pages_have_blocks():
    langs = {lang for _, lang, _ in BLOCKS}
    assert {"bash", "python", "{psbench-run}", "{psbench-python}"} <= langs and len(BLOCKS) > 25


@pytest.mark.parametrize("page,lang,body", BLOCKS, ids=[f"{p}:{i}" for i, (p, _, _) in enumerate(BLOCKS)])
def test_a_block_is_input_or_run_at_build(page, lang, body):
    assert lang in INPUT | DIRECTIVES, f"{page}: a ```{lang} block (output must come from a directive)"
    lines = [ln for ln in body.splitlines() if ln.strip() and not ln.lstrip().startswith(("#", ":"))]
    if lang == "bash":
        bad = [ln for ln in lines if not COMMANDS.match(ln.strip())]
        assert not bad, f"{page}: not commands (printed output?): {bad}"
    elif lang in ("python", "{psbench-python}"):
        assert not any(ln.startswith((">>>", "...")) for ln in lines), f"{page}: a session transcript"
        ast.parse(body)   # printed output in a code block is not Python
    elif lang == "text":  # formulas only: every line an equation
        assert all("=" in ln and not ln.startswith("psbench") for ln in lines), \
            f"{page}: a text block that is not formulas: {lines}"
    elif lang == "{psbench-run}":
        assert lines or ":image:" in body, f"{page}: an empty psbench-run block"


TRIPLE = re.compile(r'("""|\'\'\').*?\1', re.S)


def _code_text():
    """psbench's source without its triple-quoted strings (docstrings), where messages live."""
    return "\n".join(TRIPLE.sub("", p.read_text()) for p in (ROOT / "psbench").rglob("*.py"))


#: a psbench message quoted in prose: "`word: text`", not a parameter or a mapping
MESSAGE = re.compile(r"`([a-z][a-z ]*: [^`={}]+)`")


def test_quoted_messages_are_printed_by_psbench():
    quoted = sorted({m for page in PAGES for m in MESSAGE.findall(page.read_text())})
    assert quoted, "no quoted message found: the pattern no longer matches the pages"
    code = _code_text()
    for message in quoted:
        for fragment in re.split(r"\d+", message):   # the numbers are the example's
            if len(fragment.strip()) >= 6:
                assert fragment in code, \
                    f"{message!r}: psbench prints no {fragment!r} (reword the page)"


def _fenced_line(text, start):
    return next(ln.strip() for ln in text.splitlines() if ln.strip().startswith(start))


def test_setup_commands_agree():
    readme = (ROOT / "README.md").read_text()
    start = (DOCS / "getting_started.md").read_text()
    home = (DOCS / "index.md").read_text()
    ci = (ROOT / ".ci" / "run").read_text()
    first = "python3 -m venv .venv && .venv/bin/pip install -e . && .venv/bin/psbench"
    tests = ("python3 -m venv .venv && .venv/bin/pip install -e '.[test]' && "
             ".venv/bin/python -m pytest -q")
    build = _fenced_line(home, "python3 -m venv .venv && .venv/bin/pip install -e '.[docs]'")
    for cmd in (first, tests, build):
        assert cmd in readme.splitlines(), f"README lacks {cmd!r}"
    for cmd in (first, tests):
        assert cmd in start.splitlines(), f"getting_started.md lacks {cmd!r}"
    assert tests in ci.splitlines() and build in ci.splitlines(), ".ci/run runs other commands"
    assert "-W" in build.split()


def test_store_table_names_every_column():
    from psbench.harness.schema import SCHEMA

    text = (DOCS / "guide" / "store.md").read_text()
    table = {c for row in text.splitlines() if row.startswith("| `")
             for c in re.findall(r"`(\w+)`", row.split("|")[1])}
    assert set(SCHEMA.names) - table == set(), "store.md's column table lacks these columns"
    assert table - set(SCHEMA.names) == set(), "store.md's column table names unknown columns"


def _api_pages():
    """``{module: [names]}`` of the autosummary lists in docs/api/*.rst."""
    pages = {}
    for page in sorted((DOCS / "api").glob("psbench*.rst")):
        text = page.read_text()
        mod = re.search(r"^\.\. currentmodule:: (\S+)", text, re.M).group(1)
        pages[mod] = re.findall(r"^   ([A-Za-z_]\w*)\s*$", text.split(".. autosummary::", 1)[1], re.M)
    return pages


def test_api_reference_covers_the_public_names():
    """Every function and class a page's module exports (``__all__``) is documented, on
    that page or (a re-export) on another; a listed name that is gone fails too."""
    import importlib
    import inspect

    pages = _api_pages()
    assert {"psbench", "psbench.io", "psbench.forensic", "psbench.solve.validation"} <= set(pages)
    documented = set()
    for mod, names in pages.items():
        module = importlib.import_module(mod)
        for name in names:
            assert hasattr(module, name), f"docs/api/{mod}.rst lists {name}, which {mod} lacks"
            documented.add(id(getattr(module, name)))
    for mod in pages:
        module = importlib.import_module(mod)
        missing = [n for n in getattr(module, "__all__", ()) if n != "main"
                   and (inspect.isfunction(obj := getattr(module, n)) or inspect.isclass(obj))
                   and id(obj) not in documented]
        assert not missing, f"docs/api/{mod}.rst lacks {missing}"

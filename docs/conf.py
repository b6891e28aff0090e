"""Sphinx configuration of the psbench documentation.

Build (from the repository root, see docs/index.md):
``.venv/bin/pip install -e '.[docs]' && .venv/bin/sphinx-build -W --keep-going -b html docs docs/_build/html``
"""
from __future__ import annotations

import os
import re
import shutil
import sys
from pathlib import Path

import psbench

HERE = Path(__file__).resolve().parent
REPO = HERE.parent
sys.path.insert(0, str(HERE / "_ext"))

os.environ.setdefault("MPLBACKEND", "Agg")
# API stubs are regenerated on every build, so a name dropped from a list leaves no page behind
shutil.rmtree(HERE / "api" / "generated", ignore_errors=True)
# the real-data pages and examples read DiLiGenT's cat: $PSBENCH_DATA (the folder holding
# diligent/cat), else ../shared/data beside the repository, as the tests do
os.environ.setdefault("PSBENCH_DATA", str((REPO.parent / "shared" / "data").resolve()))
if not (Path(os.environ["PSBENCH_DATA"]) / "diligent" / "cat").is_dir():
    raise RuntimeError(f"DiLiGenT data not found under {os.environ['PSBENCH_DATA']}/diligent/cat: "
                       "set PSBENCH_DATA to the folder holding diligent/cat")

project = "psbench"
author = "psbench contributors"
copyright = "psbench contributors"
release = version = psbench.__version__

extensions = [
    "sphinx.ext.autodoc",
    "sphinx.ext.autosummary",
    "sphinx.ext.mathjax",
    "numpydoc",
    "myst_parser",
    "sphinx_gallery.gen_gallery",
    "psbench_run",
]

source_suffix = {".rst": "restructuredtext", ".md": "markdown"}
exclude_patterns = ["_build", "examples/README.txt", "auto_examples/*.ipynb",
                    "auto_examples/*.py", "auto_examples/*.zip", "auto_examples/*.md5",
                    "auto_examples/*.json", "sg_execution_times.rst"]
myst_enable_extensions = ["colon_fence", "deflist"]
myst_heading_anchors = 3

autosummary_generate = True
autosummary_imported_members = True
autodoc_default_options = {"members": False}
autodoc_typehints = "none"
numpydoc_show_class_members = False
numpydoc_class_members_toctree = False
numpydoc_xref_param_type = False

sphinx_gallery_conf = {
    "examples_dirs": "examples",
    "gallery_dirs": "auto_examples",
    "filename_pattern": r"/plot_",
    "run_stale_examples": True,   # every build runs every example: no stale picture
    "abort_on_example_error": False,
    "only_warn_on_example_error": False,
    "download_all_examples": False,
    "remove_config_comments": True,
    "within_subsection_order": "FileNameSortKey",
    "matplotlib_animations": False,
    "reset_modules": ("matplotlib",),
    "show_memory": False,
}

html_theme = "pydata_sphinx_theme"
html_title = f"psbench {release}"
html_theme_options = {
    "navigation_with_keys": False,
    "show_toc_level": 2,
    "secondary_sidebar_items": ["page-toc"],
    "footer_start": ["copyright"],
    "footer_end": [],
}
html_static_path = ["_static"]
html_css_files = ["psbench.css"]
html_show_sourcelink = False


# Docstrings write absolute values and norms as |x| (plain text in a terminal); in reST
# that is a substitution reference. Escape such bars outside inline literals and tables.
_BARS = re.compile(r"(?<![\\|])\|(?=[^|\s`])([^|`\n]*?[^|\s\\])\|(?!\|)")
_LITERAL = re.compile(r"(``.*?``|`[^`]*`)")


def _escape_bars(app, what, name, obj, options, lines):
    grid = any(re.fullmatch(r"\s*\+[-=+]+\+\s*", line) for line in lines)
    for i, line in enumerate(lines):
        if "|" not in line or (grid and line.lstrip().startswith(("|", "+"))):
            continue
        parts = _LITERAL.split(line)
        lines[i] = "".join(p if j % 2 else _BARS.sub(r"\\|\1\\|", p) for j, p in enumerate(parts))


def setup(app):
    app.connect("autodoc-process-docstring", _escape_bars, priority=100)

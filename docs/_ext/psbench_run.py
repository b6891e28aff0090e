"""Sphinx directives that run a documented command or snippet while the docs build.

``psbench-run`` runs shell commands (one per line, as a user would type them) and shows
each with the text it printed; ``psbench-python`` runs a Python snippet and shows the
code and its output. So no sample output in the docs is typed by hand: every build
prints what psbench prints today, and a command that fails fails the build.

Each page gets its own fresh working folder and results store (``PSBENCH_RESULTS``), so
its commands run in order on an empty store, as on a fresh checkout, and leave nothing
in the repository. The folder is shown as ``…`` in the output. Pages holding these
directives are rebuilt on every build (never served from the environment cache).
"""
from __future__ import annotations

import os
import re
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from docutils import nodes
from docutils.parsers.rst import directives
from sphinx.util import logging
from sphinx.util.docutils import SphinxDirective

logger = logging.getLogger(__name__)
TIMEOUT = 600


def _workdir(env, docname):
    root = Path(env.app.psbench_run_root)
    folder = root / docname.replace("/", "_")
    if docname not in env.app.psbench_run_fresh:  # once per page per build
        shutil.rmtree(folder, ignore_errors=True)
        folder.mkdir(parents=True)
        env.app.psbench_run_fresh.add(docname)
    return folder


def _environ(folder):
    env = dict(os.environ)
    env["PATH"] = str(Path(sys.executable).parent) + os.pathsep + env.get("PATH", "")
    env["PSBENCH_RESULTS"] = str(folder / "results")
    env.setdefault("MPLBACKEND", "Agg")
    return env


def _shorten(text, folder):
    text = text.replace(str(folder) + os.sep, "…/").replace(str(folder), "…")
    data = os.environ.get("PSBENCH_DATA")
    return text.replace(data.rstrip(os.sep), "$PSBENCH_DATA") if data else text


class _Run(SphinxDirective):
    has_content = True
    option_spec = {"hide-output": directives.flag, "stderr": directives.flag,
                   "image": directives.unchanged, "drop": directives.unchanged}

    def _execute(self, argv, shown):
        folder = _workdir(self.env, self.env.docname)
        self.env.note_dependency(__file__)
        start = time.perf_counter()
        try:
            proc = subprocess.run(argv, cwd=folder, env=_environ(folder), text=True,
                                  capture_output=True, timeout=TIMEOUT)
        except subprocess.TimeoutExpired:
            logger.warning(f"{shown!r} did not finish within {TIMEOUT} s",
                           location=self.get_location())
            return None
        logger.info(f"[psbench-run] {self.env.docname}: {shown[:60]!r} "
                    f"{time.perf_counter() - start:.1f} s")
        if proc.returncode != 0:
            logger.warning(f"{shown!r} exited with status {proc.returncode}: "
                           f"{(proc.stderr or proc.stdout).strip()[-2000:]}",
                           location=self.get_location())
            return None
        out = proc.stdout + (proc.stderr if "stderr" in self.options else "")
        if "drop" in self.options:  # lines the page says it leaves out
            drop = re.compile(self.options["drop"])
            out = "".join(ln for ln in out.splitlines(True) if not drop.search(ln))
        return _shorten(out.rstrip("\n"), folder)


class PsbenchRun(_Run):
    """Run each content line with bash; show ``$ line`` and its output."""

    def run(self):
        parts = []
        for line in self.content:
            if not line.strip():
                continue
            out = self._execute(["bash", "-c", line], line)
            if out is None:
                return []
            parts.append("$ " + line + ("\n" + out if out and "hide-output" not in
                                        self.options else ""))
        result = []
        if parts:
            text = "\n".join(parts)
            result.append(nodes.literal_block(text, text, language="console"))
        if "image" in self.options:
            result += self._image(self.options["image"])
        return result

    def _image(self, rel):
        """Show a file the page's commands wrote (copied next to the sources, ignored by git)."""
        src = _workdir(self.env, self.env.docname) / rel
        if not src.is_file():
            logger.warning(f"{rel} was not written by the commands above",
                           location=self.get_location())
            return []
        dest = Path(self.env.srcdir) / "_generated" / (
            self.env.docname.replace("/", "_") + "_" + rel.replace("/", "_"))
        dest.parent.mkdir(exist_ok=True)
        shutil.copyfile(src, dest)
        uri = "/" + dest.relative_to(self.env.srcdir).as_posix()
        return [nodes.image(uri=uri, alt=rel)]


class PsbenchPython(_Run):
    """Run the content as a Python script; show it, then what it printed."""

    def run(self):
        code = "\n".join(self.content)
        out = self._execute([sys.executable, "-c", code], code.splitlines()[0])
        if out is None:
            return []
        result = [nodes.literal_block(code, code, language="python")]
        if out and "hide-output" not in self.options:
            result.append(nodes.literal_block(out, out, language="text",
                                              classes=["psbench-output"]))
        return result


def _builder_inited(app):
    app.psbench_run_root = tempfile.mkdtemp(prefix="psbench-docs-")
    app.psbench_run_fresh = set()


def _outdated(app, env, added, changed, removed):
    # pages that run commands are re-run on every build: their output must be today's
    pages = set(getattr(env, "psbench_run_pages", ()))
    return sorted((pages & set(env.found_docs)) - set(added) - set(changed))


def _doctree_read(app, doctree):
    env = app.env
    if not hasattr(env, "psbench_run_pages"):
        env.psbench_run_pages = set()
    if env.docname in app.psbench_run_fresh:
        env.psbench_run_pages.add(env.docname)


def _finished(app, exc):
    shutil.rmtree(app.psbench_run_root, ignore_errors=True)


def setup(app):
    app.add_directive("psbench-run", PsbenchRun)
    app.add_directive("psbench-python", PsbenchPython)
    app.connect("builder-inited", _builder_inited)
    app.connect("env-get-outdated", _outdated)
    app.connect("doctree-read", _doctree_read)
    app.connect("build-finished", _finished)
    return {"version": "1", "parallel_read_safe": False, "parallel_write_safe": True}

"""The layers of ARCHITECTURE.md, checked on every import of every psbench module
(top level and inside functions): no circles between files or between packages, and
no import from a lower layer to a higher one."""
from __future__ import annotations

import ast
import re
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
PKG = REPO / "psbench"


def _modules():
    out = {}
    for path in sorted(PKG.rglob("*.py")):
        parts = list(path.relative_to(REPO).with_suffix("").parts)
        if parts[-1] == "__init__":
            parts = parts[:-1]
        out[".".join(parts)] = path
    return out


MODULES = _modules()


def _targets(name, path, node):
    if isinstance(node, ast.Import):
        found = [a.name for a in node.names]
    else:
        if node.level:
            base = name.split(".") if path.name == "__init__.py" else name.split(".")[:-1]
            base = base[:len(base) - node.level + 1]
            mod = ".".join(base + ([node.module] if node.module else []))
        else:
            mod = node.module or ""
        found = [mod] + [f"{mod}.{a.name}" for a in node.names]
    return {m for m in found if m in MODULES}


def _graph():
    g = {m: set() for m in MODULES}
    for name, path in MODULES.items():
        for node in ast.walk(ast.parse(path.read_text())):
            if isinstance(node, (ast.Import, ast.ImportFrom)):
                for t in _targets(name, path, node):
                    if t != name and not name.startswith(t + ".") and not t.startswith(name + "."):
                        g[name].add(t)
    return g


GRAPH = _graph()


def _circles(g):
    """Strongly connected components of more than one node (Tarjan, iterative)."""
    index, low, stack, on, out, counter = {}, {}, [], set(), [], [0]
    for root in g:
        if root in index:
            continue
        work = [(root, iter(sorted(g[root])))]
        index[root] = low[root] = counter[0]; counter[0] += 1
        stack.append(root); on.add(root)
        while work:
            v, it = work[-1]
            w = next(it, None)
            if w is not None:
                if w not in index:
                    index[w] = low[w] = counter[0]; counter[0] += 1
                    stack.append(w); on.add(w)
                    work.append((w, iter(sorted(g[w]))))
                elif w in on:
                    low[v] = min(low[v], index[w])
                continue
            work.pop()
            if work:
                low[work[-1][0]] = min(low[work[-1][0]], low[v])
            if low[v] == index[v]:
                comp = set()
                while True:
                    w = stack.pop(); on.discard(w); comp.add(w)
                    if w == v:
                        break
                if len(comp) > 1:
                    out.append(comp)
    return out


def _top(module):
    parts = module.split(".")
    return parts[1] if len(parts) > 1 else None


def _package_graph():
    g = {}
    for a, targets in GRAPH.items():
        ta = _top(a)
        if ta is None:
            continue
        g.setdefault(ta, set())
        for b in targets:
            tb = _top(b)
            if tb is not None and tb != ta:
                g[ta].add(tb)
                g.setdefault(tb, set())
    return g


def _layers():
    text = (REPO / "ARCHITECTURE.md").read_text()
    block = re.search(r"```layers\n(.*?)```", text, re.S).group(1)
    return [line.split() for line in block.strip().splitlines()]


LAYERS = _layers()
RANK = {name: i for i, line in enumerate(LAYERS) for name in line}


def test_graph_sees_the_imports():
    # the walk must see function-level imports too: harness.run loads the renderer lazily
    assert "psbench.render.scene" in GRAPH["psbench.harness.run"]
    assert len(MODULES) > 150


def test_no_circles_between_modules():
    assert _circles(GRAPH) == []


def test_no_circles_between_packages():
    assert _circles(_package_graph()) == []


def test_every_package_has_a_layer():
    tops = {_top(m) for m in MODULES} - {None, "conf"}
    assert tops - set(RANK) == set(), "add them to the layers of ARCHITECTURE.md"
    assert set(RANK) - tops == set(), "ARCHITECTURE.md names a layer that does not exist"


def test_imports_go_down_the_layers():
    upward = []
    for a, targets in GRAPH.items():
        for b in targets:
            ta, tb = _top(a), _top(b)
            if None in (ta, tb) or ta == tb:
                continue
            if RANK[tb] >= RANK[ta]:
                upward.append(f"{a} -> {b}")
    assert upward == []


def test_only_upper_layers_import_the_package_face():
    lowest = RANK["analysis"]
    below = sorted(m for m, ts in GRAPH.items() if "psbench" in ts and _top(m) is not None
                   and RANK.get(_top(m), lowest) < lowest)
    assert below == []


def test_top_of_the_package_is_public():
    private = sorted(p.name for p in PKG.iterdir()
                     if p.name.startswith("_") and p.name not in ("__init__.py", "__pycache__"))
    assert private == ["_shared"]


def test_no_module_over_600_lines():
    long = {m: n for m, p in MODULES.items() if (n := len(p.read_text().splitlines())) > 600}
    assert long == {}

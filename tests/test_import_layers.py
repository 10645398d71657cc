"""No import cycle: between the repository's modules, nor between its layers.

Every ``import`` of pre/, compute/, post/ and studies/ is read with ``ast`` (those inside
functions too: a deferred import hides a cycle from Python, not from the design), and two graphs
are built from them: the module graph, and the layer graph, in which each subpackage of compute
(compute.contact, compute.solvers, ...) is one node, each top-level module of compute another
(compute.run, compute.state, ...; ``compute`` itself for compute/__init__.py), and pre, post and
studies one node each. Neither may have a cycle; a failure prints every arrow of the cycle with the
import lines behind it. docs/ARCHITECTURE.md ("Layers") draws the layer graph these tests hold.
"""

from __future__ import annotations

import ast
from collections import defaultdict
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
PACKAGES = ("pre", "compute", "post", "studies")
STAGES = ("compute", "pre", "post", "studies")  # each may import only the ones before it


def module_files(root: Path = ROOT) -> dict[str, Path]:
    """Dotted module name -> file, for every .py file of ``PACKAGES`` under ``root``
    (a package is named by its __init__.py)."""
    modules = {}
    for package in PACKAGES:
        for path in sorted((root / package).rglob("*.py")):
            parts = list(path.relative_to(root).with_suffix("").parts)
            if parts[-1] == "__init__":
                parts.pop()
            modules[".".join(parts)] = path
    return modules


def imported(name: str, path: Path, modules: dict[str, Path], root: Path = ROOT) -> list[tuple[str, str]]:
    """(module imported, "file:line: statement") for every import of the module ``name`` at
    ``path`` that names one of ``modules``: ``import a.b`` imports the longest known prefix of a.b,
    ``from a import b`` imports a.b if it is a module, else a."""
    source = path.read_text()
    is_package = path.name == "__init__.py"

    def known(dotted: str) -> str | None:
        parts = dotted.split(".")
        for k in range(len(parts), 0, -1):
            if ".".join(parts[:k]) in modules:
                return ".".join(parts[:k])
        return None

    found = []
    for node in ast.walk(ast.parse(source, filename=str(path))):
        if isinstance(node, ast.Import):
            targets = [known(alias.name) for alias in node.names]
        elif isinstance(node, ast.ImportFrom):
            base = node.module or ""
            if node.level:  # relative: from the module's package, one level up per extra dot
                package = name.split(".") if is_package else name.split(".")[:-1]
                package = package[: len(package) - (node.level - 1)]
                base = ".".join(package + ([base] if base else []))
            targets = [known(f"{base}.{alias.name}") if f"{base}.{alias.name}" in modules else known(base)
                       for alias in node.names]
        else:
            continue
        where = f"{path.relative_to(root)}:{node.lineno}: {ast.get_source_segment(source, node)}"
        found += [(t, where) for t in dict.fromkeys(targets) if t is not None and t != name]
    return found


def layer(module: str) -> str:
    """The layer of a module: compute's subpackage or top-level module (its first two names), or
    the stage (pre, post, studies; compute for compute/__init__.py)."""
    parts = module.split(".")
    return ".".join(parts[:2]) if parts[0] == "compute" else parts[0]


def import_graph(modules: dict[str, Path], root: Path = ROOT) -> dict[str, dict[str, list[str]]]:
    """module -> module it imports -> the import statements behind that arrow."""
    graph: dict[str, dict[str, list[str]]] = {m: defaultdict(list) for m in modules}
    for name, path in modules.items():
        for target, where in imported(name, path, modules, root):
            graph[name][target].append(where)
    return graph


def layer_graph(graph):
    """The import graph between layers (``layer``), each arrow with the statements behind it."""
    layers: dict[str, dict[str, list[str]]] = defaultdict(lambda: defaultdict(list))
    for source, targets in graph.items():
        a = layer(source)
        layers[a]
        for target, where in targets.items():
            if a != layer(target):
                layers[a][layer(target)] += where
    return layers


def components(graph) -> list[set[str]]:
    """The strongly connected components of more than one node (Tarjan): the nodes on a cycle,
    grouped by the cycles that join them."""
    index, low, on_stack, stack, found = {}, {}, set(), [], []

    def visit(v):  # recursion depth is bounded by the number of modules (a few hundred)
        index[v] = low[v] = len(index)
        stack.append(v)
        on_stack.add(v)
        for w in graph.get(v, {}):
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on_stack:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            component = []
            while True:
                w = stack.pop()
                on_stack.discard(w)
                component.append(w)
                if w == v:
                    break
            if len(component) > 1:
                found.append(set(component))

    for v in sorted(graph):
        if v not in index:
            visit(v)
    return found


def cycles(graph) -> list[list[str]]:
    """One cycle through each of ``components(graph)`` (a shortest path back to its first
    node), as node lists [a, b, ..., a]."""
    found = []
    for component in components(graph):
        start = min(component)
        previous, frontier = {start: None}, [start]
        while frontier and start not in [w for v in frontier for w in graph[v]]:
            nxt = []
            for v in frontier:
                for w in sorted(graph[v]):
                    if w in component and w not in previous:
                        previous[w] = v
                        nxt.append(w)
            frontier = nxt
        last = next(v for v in frontier if start in graph[v])
        path = [start]
        while last is not None:
            path.append(last)
            last = previous[last]
        found.append(path[::-1])
    return found


def describe(graph, found) -> str:
    """Each cycle's arrows with the import statements behind them, after the nodes of its
    component (every one of them is on some cycle)."""
    lines = []
    for cycle in found:
        component = next(c for c in components(graph) if cycle[0] in c)
        lines.append(f"{' -> '.join(cycle)}   (on cycles: {', '.join(sorted(component))})")
        for a, b in zip(cycle, cycle[1:]):
            lines.append(f"  {a} -> {b}:")
            lines += [f"    {where}" for where in graph[a][b]]
    return "\n".join(lines)


def test_no_module_import_cycle():
    graph = import_graph(module_files())
    found = cycles(graph)
    assert not found, "import cycles between modules:\n" + describe(graph, found)


def test_no_layer_import_cycle():
    layers = layer_graph(import_graph(module_files()))
    found = cycles(layers)
    assert not found, "import cycles between layers:\n" + describe(layers, found)


def test_stages_import_downwards():
    """compute imports none of pre, post, studies; pre and post not each other nor studies."""
    layers = layer_graph(import_graph(module_files()))
    rank = {stage: k for k, stage in enumerate(STAGES)}
    stage = lambda node: node.split(".")[0]  # noqa: E731
    wrong = [f"{a} -> {b}:\n" + "\n".join(f"    {w}" for w in where)
             for a, targets in layers.items() for b, where in targets.items()
             if stage(a) != stage(b) and (rank[stage(b)] > rank[stage(a)] or {stage(a), stage(b)} == {"pre", "post"})]
    assert not wrong, "imports against the stages' order:\n" + "\n".join(wrong)


def test_walker_sees_a_cycle(tmp_path):
    """The walker itself: a cycle through a function-level and a relative import is found, and
    described with both statements."""
    (tmp_path / "compute" / "a").mkdir(parents=True)
    (tmp_path / "compute" / "__init__.py").write_text("")
    (tmp_path / "compute" / "a" / "__init__.py").write_text("")
    (tmp_path / "compute" / "a" / "x.py").write_text("def f():\n    from compute.b import y\n")
    (tmp_path / "compute" / "b.py").write_text("from .a.x import f\n")
    graph = import_graph(module_files(tmp_path), tmp_path)
    layers = layer_graph(graph)
    text = describe(layers, cycles(layers))
    assert cycles(graph) == [["compute.a.x", "compute.b", "compute.a.x"]]
    assert "compute/a/x.py:2: from compute.b import y" in text
    assert "compute/b.py:1: from .a.x import f" in text

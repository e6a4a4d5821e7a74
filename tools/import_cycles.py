"""Import cycles among the package's modules, found statically: `python tools/import_cycles.py`.

Every `import` and `from ... import` statement of every production module is read from its source
(lazy imports inside functions too, relative imports resolved), each pointing at the deepest
package module it names. The strongly connected components of that graph with more than one module
are the cycles; the tool prints each and exits 1 when there is one. Tests, benches, tools and the
sample scenes' scripts are not production modules.
"""

from __future__ import annotations

import ast
import sys
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
PACKAGE = "classic_bake"
NOT_PRODUCTION = {"tests", "bench", "tools", "sample_blends", "docs", "requirements", "out", "dist",
                  "wheels"}


def modules(root: Path = REPO) -> dict[str, Path]:
    """{dotted module name: source file} of every production module under `root`."""
    found = {}
    for path in sorted(root.rglob("*.py")):
        rel = path.relative_to(root)
        if rel.parts[0] in NOT_PRODUCTION or any(p.startswith(".") for p in rel.parts):
            continue
        parts = list(rel.with_suffix("").parts)
        if parts[-1] == "__init__":
            parts = parts[:-1]
        found[".".join([PACKAGE, *parts])] = path
    return found


def _imported(node: ast.AST, package: str, known) -> list[str]:
    """The names an import statement imports: `from p import m` names the module p.m when there
    is one (p's own `__init__` is not counted then), else p."""
    if isinstance(node, ast.Import):
        return [alias.name for alias in node.names]
    if isinstance(node, ast.ImportFrom):
        if node.level:
            base = package.split(".")[: len(package.split(".")) - (node.level - 1)]
            module = ".".join(base + ([node.module] if node.module else []))
        else:
            module = node.module or ""
        return [f"{module}.{a.name}" if f"{module}.{a.name}" in known else module
                for a in node.names]
    return []


def import_graph(root: Path = REPO) -> dict[str, set[str]]:
    """{module: the package modules its import statements name}."""
    known = modules(root)
    graph = {}
    for name, path in known.items():
        package = name if path.name == "__init__.py" else name.rsplit(".", 1)[0]
        targets = set()
        for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"), str(path))):
            for target in _imported(node, package, known):
                while target and target not in known:  # the package module it lies in
                    target = target.rsplit(".", 1)[0] if "." in target else ""
                if target and target != name:
                    targets.add(target)
        graph[name] = targets
    return graph


def cycles(graph: dict[str, set[str]]) -> list[list[str]]:
    """The strongly connected components of more than one module (Tarjan, iterative)."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on_stack: set[str] = set()
    found = []
    for start in graph:
        if start in index:
            continue
        work = [(start, iter(sorted(graph[start])))]
        index[start] = low[start] = len(index)
        stack.append(start)
        on_stack.add(start)
        while work:
            node, children = work[-1]
            child = next(children, None)
            if child is not None:
                if child not in index:
                    index[child] = low[child] = len(index)
                    stack.append(child)
                    on_stack.add(child)
                    work.append((child, iter(sorted(graph.get(child, ())))))
                elif child in on_stack:
                    low[node] = min(low[node], index[child])
                continue
            work.pop()
            if work:
                low[work[-1][0]] = min(low[work[-1][0]], low[node])
            if low[node] == index[node]:
                component = []
                while True:
                    member = stack.pop()
                    on_stack.discard(member)
                    component.append(member)
                    if member == node:
                        break
                if len(component) > 1:
                    found.append(sorted(component))
    return sorted(found)


def main() -> int:
    found = cycles(import_graph())
    for component in found:
        print("import cycle: " + " <-> ".join(m.removeprefix(f"{PACKAGE}.") for m in component))
    if not found:
        print("import_cycles: none")
    return 1 if found else 0


if __name__ == "__main__":
    sys.exit(main())

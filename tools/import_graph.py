"""Print import cycles and upward (layer-breaking) imports among the jointid modules.

Usage: ``python tools/import_graph.py [src/jointid]`` (default: ``src/jointid`` under the working directory).  Reads every ``import`` statement (module level and
inside functions, not under ``if TYPE_CHECKING``) with ``ast``; prints nothing and exits 0 when the graph is clean.
"""
import ast
import sys
from pathlib import Path

LAYERS = ["errors", "io", "yamlio", "threads", "correlate", "data", "config", "geometry", "fe",
          "identification", "response", "diagnosis", "reporting", "stages", "cli"]


def module_name(path: Path, root: Path) -> str:
    parts = list(path.relative_to(root.parent).with_suffix("").parts)
    if parts[-1] == "__init__":
        parts = parts[:-1]
    return ".".join(parts)


def imports(path: Path, name: str) -> set[str]:
    out = set()
    tree = ast.parse(path.read_text())
    typing_only = set()
    for node in ast.walk(tree):  # imports under `if TYPE_CHECKING:` are for annotations only
        if isinstance(node, ast.If) and getattr(node.test, "id", getattr(node.test, "attr", "")) == "TYPE_CHECKING":
            typing_only.update(id(n) for stmt in node.body for n in ast.walk(stmt))
    for node in ast.walk(tree):
        if id(node) in typing_only:
            continue
        if isinstance(node, ast.ImportFrom) and node.module and node.module.startswith("jointid"):
            out.add(node.module)
            out.update(f"{node.module}.{a.name}" for a in node.names)
        elif isinstance(node, ast.Import):
            out.update(a.name for a in node.names if a.name.startswith("jointid"))
    return out


def layer(mod: str) -> int:
    parts = mod.split(".")
    return LAYERS.index(parts[1]) if len(parts) > 1 and parts[1] in LAYERS else -1


def main(argv):
    root = Path(argv[1]) if len(argv) > 1 else Path.cwd() / "src" / "jointid"  # the checkout you stand in
    mods = {module_name(p, root): p for p in root.rglob("*.py")}
    graph = {m: {i for i in imports(p, m) if i in mods and i != m} for m, p in mods.items()}
    bad = 0
    for m, deps in sorted(graph.items()):
        for d in sorted(deps):
            if layer(d) > layer(m) >= 0 and not m.endswith("__main__"):
                print(f"upward import: {m} -> {d}")
                bad += 1
    # cycles (Tarjan)
    index, low, stack, on, sccs, counter = {}, {}, [], set(), [], [0]

    def strong(v):
        index[v] = low[v] = counter[0]
        counter[0] += 1
        stack.append(v)
        on.add(v)
        for w in graph[v]:
            if w not in index:
                strong(w)
                low[v] = min(low[v], low[w])
            elif w in on:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            comp = []
            while True:
                w = stack.pop()
                on.discard(w)
                comp.append(w)
                if w == v:
                    break
            if len(comp) > 1:
                sccs.append(sorted(comp))

    sys.setrecursionlimit(10000)
    for v in graph:
        if v not in index:
            strong(v)
    for comp in sccs:
        print("cycle: " + " <-> ".join(comp))
        bad += 1
    return 1 if bad else 0


if __name__ == "__main__":
    sys.exit(main(sys.argv))

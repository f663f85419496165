"""Check the package's layout: import layers, cycles, and the size of modules and functions.

Usage: ``python tools/layout.py [src/jointid]`` (default: ``src/jointid`` under the working directory).
Prints one line per finding and exits 1 if there is any; prints nothing and exits 0 when clean.

* Imports (every ``import`` statement, at module level, inside functions and under
  ``if TYPE_CHECKING``) point only down the layers of ``LAYERS`` (docs/architecture.md), and no
  modules import each other in a cycle, not even for annotations: a lower layer defines the
  protocol it needs (e.g. :class:`jointid.fe.affine.AffineModel`).
* No module is over 600 lines unless a comment among its first 40 lines starts with
  ``# over 600 lines:`` and gives the reason (one concern per module is the rule; the number only catches
  a module that has become several, and no module should be cut to fit it); no function is over 80 lines unless a comment at its top
  (before or right after its docstring) starts with ``# long`` and gives the reason.
* No function outside the configuration layer (``CONFIG_LAYERS``: ``config/``, where the dict is read and
  made typed objects) takes the whole configuration (a parameter named ``cfg`` or ``config``, or ending in
  ``_cfg``/``_config``): every other module of the package, ``cli`` included, takes the typed objects of
  :mod:`jointid.config.typed`, :mod:`jointid.config.options` ... or plain numbers.  The rule adapters
  (``workflow/scripts/``) and the Snakefile are outside the package: they hold the dict and build the typed
  options once.  No function takes more than 8 parameters (positional and keyword-only, without
  ``self``/``cls``, ``*args`` and ``**kwargs``) unless a comment at its top starts with
  ``# many parameters:`` and gives the reason.
"""
import ast
import sys
from pathlib import Path

LAYERS = ["errors", "io_errors", "io", "yamlio", "threads", "correlate", "data", "config", "ema", "geometry", "fe",
          "identification", "response", "diagnosis", "reconstruction", "synthetic", "reporting", "stages", "api", "cli"]


def module_name(path: Path, root: Path) -> str:
    parts = list(path.relative_to(root.parent).with_suffix("").parts)
    if parts[-1] == "__init__":
        parts = parts[:-1]
    return ".".join(parts)


def eager(path: Path) -> bool:
    """Whether the module at ``path`` imports package modules when it is loaded (a top-level ``import``
    of ``jointid``, not under ``if TYPE_CHECKING`` nor inside a function)."""
    for node in ast.parse(path.read_text()).body:
        if isinstance(node, ast.ImportFrom) and (node.module or "").startswith("jointid"):
            return True
        if isinstance(node, ast.Import) and any(a.name.startswith("jointid") for a in node.names):
            return True
    return False


def imports(path: Path, name: str, modules=(), eager_packages=()) -> set[str]:
    """The package modules ``path`` imports: every ``import`` statement, at module level, inside functions
    and under ``if TYPE_CHECKING`` (an annotation that names a module is a dependency on it too).
    ``from pkg import name`` depends on the module ``pkg.name`` where that is one of ``modules``, and on
    the package ``pkg`` only where its ``__init__`` imports package modules when loaded
    (``eager_packages``; a lazy ``__init__`` is only passed through); else on ``pkg``."""
    out = set()
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.ImportFrom) and node.module and node.module.startswith("jointid"):
            subs = {f"{node.module}.{a.name}" for a in node.names}
            named = subs & set(modules)
            out.update(named)
            if len(named) < len(subs) or node.module in eager_packages:
                out.add(node.module)
        elif isinstance(node, ast.Import):
            out.update(a.name for a in node.names if a.name.startswith("jointid"))
    return out


def layer(mod: str) -> int:
    parts = mod.split(".")
    return LAYERS.index(parts[1]) if len(parts) > 1 and parts[1] in LAYERS else -1


MAX_MODULE_LINES, MAX_FUNCTION_LINES, MAX_PARAMETERS = 600, 80, 8
CONFIG_LAYERS = ("config",)
"""The layer that reads the configuration dict and turns it into typed objects (docs/architecture.md)."""
CONFIG_FREE = tuple(name for name in LAYERS if name not in CONFIG_LAYERS)
"""Layers whose functions take typed objects or numbers, never the whole configuration: all but
``CONFIG_LAYERS`` (and so are the package's modules outside ``LAYERS``, e.g. ``progress``)."""
CONFIG_NAMES = ("cfg", "config")
"""Parameter names of a configuration dict (also as a suffix: ``damping_cfg``, ``rig_config``)."""


def _config_name(name: str) -> bool:
    return name in CONFIG_NAMES or name.endswith(tuple("_" + n for n in CONFIG_NAMES))


def _functions(tree: ast.AST):
    return (n for n in ast.walk(tree) if isinstance(n, (ast.FunctionDef, ast.AsyncFunctionDef)))


def _head(lines: list[str], node) -> list[str]:
    """The stripped lines of a function from its ``def`` to just past its docstring (where a reason goes)."""
    first = node.body[0]
    doc = isinstance(first, ast.Expr) and isinstance(first.value, ast.Constant)
    end = first.end_lineno + 3 if doc else first.lineno + 2
    return [ln.strip() for ln in lines[node.lineno - 1:end]]


def parameter_findings(path: Path, config_free: bool = False) -> list[str]:
    """Functions of ``path`` with more than 8 parameters and no ``# many parameters: <reason>`` comment at
    their top, and (``config_free``: a module outside ``CONFIG_LAYERS``) those taking ``cfg`` or ``config``."""
    lines = path.read_text().splitlines()
    out = []
    for node in _functions(ast.parse("\n".join(lines))):
        a = node.args
        names = [x.arg for x in a.posonlyargs + a.args + a.kwonlyargs if x.arg not in ("self", "cls")]
        if config_free:
            out += [f"{path}:{node.lineno}: {node.name} takes {n!r}, the whole configuration — take the typed "
                    "objects of jointid.config (typed, options ...), built once at the edge, or numbers"
                    for n in names if _config_name(n)]
        if len(names) > MAX_PARAMETERS and not any(h.startswith("# many parameters:") for h in _head(lines, node)):
            out.append(f"{path}:{node.lineno}: {node.name} takes {len(names)} parameters, no '# many parameters: "
                       "<reason>' comment at its top")
    return out


def size_findings(path: Path) -> list[str]:
    """Modules over 600 lines and functions over 80 lines of ``path`` that carry no reason comment."""
    lines = path.read_text().splitlines()
    out = []
    mark = f"# over {MAX_MODULE_LINES} lines:"
    if len(lines) > MAX_MODULE_LINES and not any(ln.startswith(mark) for ln in lines[:40]):
        out.append(f"{path}: {len(lines)} lines, no '{mark} <reason>' comment at its top")
    for node in _functions(ast.parse("\n".join(lines))):
        n = node.end_lineno - node.lineno + 1
        if n <= MAX_FUNCTION_LINES:
            continue
        if not any(h.startswith("# long") for h in _head(lines, node)):
            out.append(f"{path}:{node.lineno}: {node.name} is {n} lines, no '# long ...: <reason>' comment at "
                       "its top")
    return out


def main(argv):
    root = Path(argv[1]) if len(argv) > 1 else Path.cwd() / "src" / "jointid"  # the checkout you stand in
    mods = {module_name(p, root): p for p in root.rglob("*.py")}
    eager_pkgs = {m for m, p in mods.items() if p.name == "__init__.py" and eager(p)}
    graph = {m: {i for i in imports(p, m, mods, eager_pkgs) if i in mods and i != m} for m, p in mods.items()}
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
    for p in sorted(mods.values()):
        config_free = Path(p.relative_to(root).parts[0]).stem not in CONFIG_LAYERS
        for line in size_findings(p) + parameter_findings(p, config_free):
            print(line)
            bad += 1
    return 1 if bad else 0


if __name__ == "__main__":
    sys.exit(main(sys.argv))

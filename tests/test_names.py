"""No name used that is not defined: every Python file of the project, read with :mod:`symtable`.

A name a function reads from the module scope must be defined there (assigned, imported, a def or a
class) or be a builtin.  Caught in session 64: the coverage benchmark called ``DiagnosisSettings`` without
importing it after a mechanical edit, and every case of a 48-case run failed with a NameError; no test
ran that line.
"""

from __future__ import annotations

import builtins
import symtable
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
FOLDERS = ("src", "workflow/scripts", "benchmarks", "tools", "tests", "docs/examples")
MODULE_NAMES = {"__file__", "__name__", "__doc__", "__builtins__", "__spec__", "__path__", "__loader__"}
INJECTED = {"workflow/scripts": {"snakemake"}}
"""Names a runner puts in a file's scope: Snakemake gives every rule script ``snakemake``."""


def undefined_names(path: Path, injected: set[str] = frozenset()) -> list[str]:
    """``"<line> <scope>: <name>"`` for each name read in ``path`` that no scope defines."""
    top = symtable.symtable(path.read_text(), str(path), "exec")
    symbols = top.get_symbols()
    if any(s.get_name() == "*" for s in symbols):  # a star import defines what it likes
        return []
    known = {s.get_name() for s in symbols if s.is_assigned() or s.is_imported() or s.is_namespace()}
    known |= set(dir(builtins)) | MODULE_NAMES | set(injected)
    out = []

    def walk(table) -> None:
        module = table.get_type() == "module"
        for s in table.get_symbols():
            free_here = s.is_global() or (module and not (s.is_assigned() or s.is_imported()))
            if s.is_referenced() and free_here and s.get_name() not in known:
                out.append(f"{table.get_lineno()} {table.get_name()}: {s.get_name()}")
        for child in table.get_children():
            walk(child)

    walk(top)
    return out


def test_the_checker_finds_a_name_never_defined(tmp_path):
    f = tmp_path / "m.py"
    f.write_text("import x\n\ndef f():\n    return y + x\n\nclass C:\n    z = 1\n\n    def g(self):\n        return z\n")
    assert undefined_names(f) == ["3 f: y", "9 g: z"]  # a class body's names are no scope of its methods


@pytest.mark.parametrize("folder", FOLDERS)
def test_every_name_used_is_defined(folder):
    bad = [f"{p.relative_to(ROOT)}:{line}" for p in sorted((ROOT / folder).rglob("*.py"))
           for line in undefined_names(p, INJECTED.get(folder, set()))]
    assert not bad, "names used but never defined (a missing import?):\n" + "\n".join(bad)

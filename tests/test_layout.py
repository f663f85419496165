"""The package's layout (docs/architecture.md): imports point down the layers, no cycles, small modules."""
import importlib.util
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
spec = importlib.util.spec_from_file_location("layout", ROOT / "tools" / "layout.py")
layout = importlib.util.module_from_spec(spec)
spec.loader.exec_module(layout)


def test_package_layout_is_clean():
    proc = subprocess.run([sys.executable, str(ROOT / "tools" / "layout.py"), str(ROOT / "src" / "jointid")],
                          capture_output=True, text=True)
    assert proc.returncode == 0 and proc.stdout == "", proc.stdout


def test_size_check_flags_a_long_function_without_a_reason(tmp_path):
    body = "\n".join(f"    x{i} = {i}" for i in range(85))
    plain = tmp_path / "plain.py"
    plain.write_text(f'def f():\n    """Doc."""\n{body}\n')
    reasoned = tmp_path / "reasoned.py"
    reasoned.write_text(f'def f():\n    """Doc."""\n    # long: one table of constants\n{body}\n')
    assert len(layout.size_findings(plain)) == 1 and "f is 87 lines" in layout.size_findings(plain)[0]
    assert layout.size_findings(reasoned) == []


def test_layer_check_flags_an_upward_import_and_a_cycle(tmp_path):
    pkg = tmp_path / "jointid"
    (pkg / "fe").mkdir(parents=True)
    (pkg / "stages").mkdir()
    for f in (pkg / "__init__.py", pkg / "fe" / "__init__.py", pkg / "stages" / "__init__.py"):
        f.write_text("")
    (pkg / "fe" / "a.py").write_text("from jointid.stages.b import g\n")
    (pkg / "stages" / "b.py").write_text("def g():\n    from jointid.fe.a import g\n")
    proc = subprocess.run([sys.executable, str(ROOT / "tools" / "layout.py"), str(pkg)], capture_output=True, text=True)
    assert proc.returncode == 1
    assert "upward import: jointid.fe.a -> jointid.stages.b" in proc.stdout
    assert "cycle: jointid.fe.a <-> jointid.stages.b" in proc.stdout

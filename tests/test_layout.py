"""The package's layout (docs/architecture.md): imports point down the layers, no cycles, small modules,
no whole configuration in the domain layers and no more than 8 parameters without a reason."""
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


def test_parameter_check_flags_cfg_in_a_domain_layer_and_many_parameters_without_a_reason(tmp_path):
    src = tmp_path / "mod.py"
    src.write_text("def solve(cfg, model):\n    return model\n\n\n"
                   "def damp(damping_cfg, f):\n    return f\n\n\n"
                   "def wide(a, b, c, d, e, f, g, h, i, *args, **kwargs):\n    return a\n\n\n"
                   "def reasoned(self, a, b, c, d, e, f, g, h, *, i=0):\n"
                   "    # many parameters: one per file of a workflow rule\n    return a\n\n\n"
                   "def eight(a, b, c, d, e, f, g, *, h=0, **kwargs):\n    return a\n")
    domain = layout.parameter_findings(src, config_free=True)
    assert len(domain) == 3
    assert "solve takes 'cfg'" in domain[0] and "damp takes 'damping_cfg'" in domain[1]
    assert "wide takes 9 parameters" in domain[2]
    assert layout.parameter_findings(src) == [domain[2]]  # in the configuration layer cfg is fine


def test_parameter_check_finds_config_outside_the_configuration_layer_of_a_package(tmp_path):
    """Every layer but config/ (stages, api, diagnosis ... and the top-level modules) takes typed options."""
    pkg = tmp_path / "jointid"
    for layer in ("fe", "stages", "api", "diagnosis", "config"):
        (pkg / layer).mkdir(parents=True)
        (pkg / layer / "__init__.py").write_text("")
    (pkg / "__init__.py").write_text("")
    (pkg / "fe" / "a.py").write_text("def build(config):\n    return config\n")
    (pkg / "stages" / "b.py").write_text("def run(cfg):\n    return cfg\n")
    (pkg / "api" / "d.py").write_text("class Study:\n    def __init__(self, config):\n        self.c = config\n")
    (pkg / "diagnosis" / "e.py").write_text("def diagnose(system, effects_cfg):\n    return system\n")
    (pkg / "cli.py").write_text("def main(run_config):\n    return run_config\n")
    (pkg / "config" / "c.py").write_text("def load(cfg):\n    return cfg\n")
    proc = subprocess.run([sys.executable, str(ROOT / "tools" / "layout.py"), str(pkg)], capture_output=True, text=True)
    assert proc.returncode == 1
    assert "a.py:1: build takes 'config'" in proc.stdout and "b.py:1: run takes 'cfg'" in proc.stdout
    assert "d.py:2: __init__ takes 'config'" in proc.stdout and "e.py:1: diagnose takes 'effects_cfg'" in proc.stdout
    assert "cli.py:1: main takes 'run_config'" in proc.stdout
    assert "c.py" not in proc.stdout  # the configuration layer reads the dict


def test_a_cycle_through_annotations_only_is_a_cycle_and_a_lazy_package_is_passed_through(tmp_path):
    """``if TYPE_CHECKING`` imports count (issue 53: no cycles, not even for annotations).  ``from pkg
    import mod`` depends on ``pkg`` only where ``pkg/__init__.py`` imports package modules when loaded."""
    pkg = tmp_path / "jointid"
    (pkg / "fe").mkdir(parents=True)
    (pkg / "__init__.py").write_text("from typing import TYPE_CHECKING\nif TYPE_CHECKING:\n    from jointid.fe.b import h\n")
    (pkg / "fe" / "__init__.py").write_text("")
    (pkg / "io.py").write_text("")
    (pkg / "fe" / "a.py").write_text("from typing import TYPE_CHECKING\nif TYPE_CHECKING:\n    from jointid.fe.b import h\n")
    (pkg / "fe" / "b.py").write_text("from jointid import io\nfrom jointid.fe.a import g\n")
    proc = subprocess.run([sys.executable, str(ROOT / "tools" / "layout.py"), str(pkg)], capture_output=True, text=True)
    assert proc.returncode == 1
    assert proc.stdout.splitlines() == ["cycle: jointid.fe.a <-> jointid.fe.b"], proc.stdout
    (pkg / "__init__.py").write_text("from jointid.fe.b import h\n")  # loaded eagerly: b -> jointid -> b
    proc = subprocess.run([sys.executable, str(ROOT / "tools" / "layout.py"), str(pkg)], capture_output=True, text=True)
    assert "cycle: jointid <-> jointid.fe.a <-> jointid.fe.b" in proc.stdout, proc.stdout


def test_every_rule_script_ends_with_its_one_run_script_call():
    """A job that succeeded ends its process inside run_script (jointid.stages.runner._leave): nothing after it would run."""
    import ast

    scripts = sorted((ROOT / "workflow" / "scripts").glob("*.py"))
    assert scripts
    for path in scripts:
        tree = ast.parse(path.read_text())
        calls = [n for n in ast.walk(tree) if isinstance(n, ast.Call) and getattr(n.func, "id", "") == "run_script"]
        last = tree.body[-1]
        assert len(calls) == 1 and isinstance(last, ast.Expr) and last.value is calls[0], path.name

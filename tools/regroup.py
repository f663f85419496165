"""One-off: move the flat package into layered subpackages and rewrite every import (kept for the record)."""
import re, subprocess, sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
PKG = ROOT / "src" / "jointid"
MAP = {
    "config": "config.core", "workflowconfig": "config.snakefile",
    "workflow": "stages.runner", "stages": "stages.core",
    "measured": "data.dataset", "uff": "data.uff", "synth": "data.synth",
    "rig": "geometry.rig", "points": "geometry.points", "mesh": "geometry.mesh", "localrefine": "geometry.localrefine",
    "fem": "fe.fem", "model": "fe.model", "modal": "fe.modal", "pencil": "fe.pencil", "reduced": "fe.reduced",
    "rom": "fe.rom", "extrapolate": "fe.extrapolate", "describe": "fe.describe", "vtk": "fe.vtk",
    "correlate": "correlate.pairing", "tracking": "identification.tracking",
    "doe": "identification.doe", "surface": "identification.surface", "identify": "identification.identify",
    "updating": "identification.updating", "meshcheck": "identification.meshcheck",
    "harmonic": "response.harmonic", "frf": "response.drive_point", "damping": "response.damping",
    "emforce": "response.emforce", "blockrigidity": "response.carriage",
    "diagnose": "diagnosis.core", "effects": "diagnosis.effects",
    "report": "reporting.page", "report_tables": "reporting.tables", "figures": "reporting.figures",
    "provenance": "reporting.provenance", "checks": "reporting.checks",
}
NAMES = "|".join(sorted(MAP, key=len, reverse=True))


def rewrite(text: str, own: str | None) -> str:
    # from . import a, b as c   /  from jointid import a, b as c
    def from_pkg(m):
        indent, items = m.group(1), m.group(3)
        out = []
        for item in [s.strip() for s in items.split(",")]:
            name, _, alias = item.partition(" as ")
            name, alias = name.strip(), alias.strip()
            if name in MAP:
                parent, _, leaf = MAP[name].rpartition(".")
                out.append(f"{indent}from jointid.{parent} import {leaf}" + (f" as {alias}" if alias else (f" as {name}" if leaf != name else "")))
            else:
                out.append(f"{indent}from jointid import {item}")
        return "\n".join(out)
    text = re.sub(r"^([ \t]*)from (\.|jointid) import ([A-Za-z_][\w ,]*?)[ \t]*$", from_pkg, text, flags=re.M)
    # from .x import / from jointid.x import
    text = re.sub(rf"from \.({NAMES})\b", lambda m: f"from jointid.{MAP[m.group(1)]}", text)
    text = re.sub(r"from \.\.?(\w)", r"from jointid.\1", text) if own else text
    text = re.sub(rf"\bjointid\.({NAMES})\b(?![\w/])", lambda m: f"jointid.{MAP[m.group(1)]}", text)
    return text


def main():
    subprocess.run(["git", "-C", str(ROOT), "stash", "list"], check=True)
    for sub in sorted({v.split(".")[0] for v in MAP.values()}):
        d = PKG / sub
        d.mkdir(exist_ok=True)
    for old, new in MAP.items():
        dest = PKG / (new.replace(".", "/") + ".py")
        subprocess.run(["git", "-C", str(ROOT), "mv", str(PKG / f"{old}.py"), str(dest)], check=True)
    for sub in sorted({v.split(".")[0] for v in MAP.values()}):
        init = PKG / sub / "__init__.py"
        if not init.exists():
            init.write_text(f'"""jointid.{sub}."""\n')
    files = [p for p in ROOT.rglob("*") if p.is_file() and ".git" not in p.parts and ".venv" not in p.parts
             and (p.suffix in (".py", ".md", ".smk", ".yaml", ".rst", ".toml", ".sh") or p.name in ("Snakefile", "run", "Makefile"))
             and p.name != "regroup.py"]
    for p in files:
        t = p.read_text()
        n = rewrite(t, own=str(p).startswith(str(PKG)))
        if n != t:
            p.write_text(n)
            print("rewrote", p.relative_to(ROOT))


if __name__ == "__main__":
    main()

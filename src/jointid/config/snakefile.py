"""Config handling inside the Snakefile: validate once at start, hand sections to rules."""

from __future__ import annotations

import copy
import re
import sys
from pathlib import Path

from jointid.config.load import load_config
from jointid.config.rule_keys import ROM as CONFIG_ROM, ROM_KEYS  # modal_keys below
from jointid.errors import ConfigError
from jointid.yamlio import deep_merge

__all__ = ["attribute", "ema_sources", "merged", "mesh_inputs", "mesh_keys", "modal_keys", "run_folders", "sections",
           "validated"]


def run_folders(config: dict) -> tuple[str, str, str]:
    """``(results, logs, benchmarks)`` folders of the study: ``results``, ``logs``, ``benchmarks/out``
    without a ``run.name``, else ``results/<name>``, ``logs/<name>``, ``benchmarks/out/<name>`` (one study,
    one folder: two configurations in one working folder never write over each other)."""
    name = str(((config.get("run") or {}).get("name")) or "")
    if not name:
        return "results", "logs", "benchmarks/out"
    return f"results/{name}", f"logs/{name}", f"benchmarks/out/{name}"


def validated(config: dict, configfiles=()) -> dict:
    """Validate (and fill defaults of) the Snakemake config; on error print the lines and exit 1.

    Snakemake has already merged the ``--configfile`` files (deeply, later files win; a ``null``
    there survives and removes the key, as in :func:`jointid.config.load.check_config`).  The measured
    dataset folders are checked too (relative to the working directory, as the rules read them),
    so a misnamed dataset stops the run here instead of as a missing input or a stale result.
    ``configfiles`` (the ``--configfile`` files, in order) name the file each problem's key came
    from (:func:`attribute`); without them every line says ``config.yaml``.
    """
    from jointid.config.remembered import validated_once

    try:  # remembered from an earlier start with the same inputs (jointid.config.remembered): about 0.5 s less
        return validated_once(dict(config), lambda raw: load_config(raw, check_datasets=True))
    except ConfigError as exc:
        print("\n".join(attribute(exc.problems, [str(f) for f in configfiles])), file=sys.stderr)
        sys.exit(1)


def attribute(lines: list[str], configfiles: list[str], default: str = "config.yaml") -> list[str]:
    """Problem lines ``config.yaml: <key>: ...`` relabelled with the config file that set ``<key>``.

    The file defining the longest prefix of the key wins, the later one on a tie (as Snakemake
    merges them); a key no file defines keeps ``default``.
    """
    from jointid.yamlio import read_yaml  # noqa: PLC0415

    docs = []
    for f in configfiles:
        try:
            docs.append((f, read_yaml(Path(f), f) or {}))
        except Exception:  # noqa: BLE001 - an unreadable file names nothing
            continue
    out = []
    for line in lines:
        head = f"{default}: "
        if not line.startswith(head) or not docs:
            out.append(line)
            continue
        key = line[len(head):].split(": ", 1)[0]
        parts = [p for p in re.split(r"\.|\[\d+\]", key) if p]
        best, depth = default, 0
        for name, doc in docs:
            node, d = doc, 0
            for p in parts:
                if isinstance(node, dict) and p in node:
                    node, d = node[p], d + 1
                else:
                    break
            if d >= depth and d > 0:
                best, depth = name, d
        out.append(f"{best}: {line[len(head):]}")
    return out


def sections(config: dict, *names: str) -> dict:
    """A deep copy of the named parts of ``config`` (for ``params: cfg=``), nested as in ``config``.

    A name is a top-level section (``"rig"``) or a dotted path to a key inside one
    (``"harmonic.band_Hz"``, ``"states.power_on"``): a rule then depends on that key only, so
    changing another key of the section does not rerun it.  Names that are absent are skipped.

    Examples
    --------
    >>> sections({"a": {"x": 1, "y": 2}, "b": 3}, "a.x", "b")
    {'a': {'x': 1}, 'b': 3}
    """
    out: dict = {}
    for name in names:
        parts = name.split(".")
        node = config
        try:
            for p in parts:
                node = node[p]
        except (KeyError, TypeError):
            continue
        dest = out
        for p in parts[:-1]:
            dest = dest.setdefault(p, {})
        dest[parts[-1]] = copy.deepcopy(node)
    return out


def merged(*cfgs: dict) -> dict:
    """Deep union of several rules' config parts (later ones win on conflicting leaves).

    Used for the provenance of a result that depends on a chain of rules: the union of the parts
    every rule of the chain takes.

    Examples
    --------
    >>> merged({"a": {"x": 1}, "b": 1}, {"a": {"y": 2}, "b": 2})
    {'a': {'x': 1, 'y': 2}, 'b': 2}
    """
    out: dict = {}
    for cfg in cfgs:
        out = deep_merge(out, cfg)
    return out


PAPER_DATASET = "data/paper"
"""The paper's measured dataset: its tables are compared with the paper's values."""


def paper_input(config: dict, path: str) -> str | list:
    """``path`` (a file of the paper's values) as a rule input when the run's measured dataset is the
    paper's, else no input: on other data the tables' paper columns stay empty."""
    import os

    return path if os.path.normpath(config["measurements"]["dataset"]) == PAPER_DATASET else []


def mesh_inputs(config: dict) -> list[str]:
    """Files rule ``mesh`` reads the model from: with ``model.kind: mesh`` the mesh file and the measuring
    points (so that a changed file rebuilds the model), none for the parametric rig."""
    m = config.get("model") or {}
    return [m["path"], m["points"]] if m.get("kind") == "mesh" else []


def mesh_keys(config: dict) -> tuple[str, ...]:
    """Config keys of rule ``mesh``: the mesh, not whether and how identify extrapolates over its
    edge levels (``mesh.extrapolate_edges``, ``mesh.edge_ratio``)."""
    if (config.get("model") or {}).get("kind") == "mesh":
        return ("materials", "model")
    return ("materials", "rig", "model",
            *(f"mesh.{k}" for k in config["mesh"] if k not in ("extrapolate_edges", "edge_ratio")))




def modal_keys(config: dict) -> tuple[str, ...]:
    """Config keys of rules ``modal`` and ``modal_zoom``.

    With ``solver.method: full`` they leave out the ROM keys (:data:`ROM_KEYS`), so that the full
    path's jobs, params and results stay exactly those it had before the option existed; with
    ``reduced`` (the default) they hold the method (a switch reruns the DOE solves) but not the
    ROM's tolerance.
    """
    method = config["solver"]["method"]
    if method == "rom":
        return CONFIG_ROM
    left_out = ROM_KEYS if method == "full" else ("rom_tolerance",)
    return ("materials", "rig", "model", "joints", *(f"solver.{k}" for k in config["solver"] if k not in left_out))


def ema_sources(config: dict) -> dict[str, str]:
    """The named FRF sources of ``ema.sources`` (rule ``ema``; empty without an ``ema`` section)."""
    return {str(k): str(v) for k, v in ((config.get("ema") or {}).get("sources") or {}).items()}

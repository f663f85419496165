"""Configuration layer: load config.yaml, fill defaults, validate, hash, document.

The JSON-Schema ``schema.yaml`` shipped in this package is the single source of the keys, types,
ranges, defaults and descriptions; the modules add what a schema cannot express and turn every
problem into one user-facing line (all problems raised together as one
:class:`jointid.errors.ConfigError`).

Modules
-------
load
    :func:`load_config`, :func:`check_config`, :func:`section`: read, merge overrides, validate.
schema
    The schema from the package (:func:`find_schema`, :func:`load_schema`) and the defaults it fills.
messages
    jsonschema errors and values as one-line user messages (unit words, ranges, suggestions).
checks
    Semantic checks across keys (materials, joints, DOE, harmonic, solver).
rig
    Semantic checks of the rig geometry and the mesh size (:func:`estimate_node_count`).
datasets
    The one state → dataset rule (:func:`dataset_folder`), :func:`registered_datasets` and the
    checks of states and dataset folders.
hashing
    :func:`config_hash`, the stable short hash of a configuration or of some sections; the
    :class:`~jointid.config.hashing.ConfigStamp` (hash and sections) a provenance record keeps.
reference
    :func:`config_reference_markdown`, the generator of ``docs/config-reference.md``.
snakefile
    Helpers the Snakefile uses (``validated``, ``sections``, ``merged``, the config keys of rules
    ``mesh`` and ``modal``).
typed, typed_mesh
    The validated configuration as frozen dataclasses (:class:`~jointid.config.typed.Settings`,
    :class:`~jointid.config.typed.ModelSpec` ...), what the domain layers take instead of the dict.
options
    The stages' typed options (:class:`~jointid.config.options.DoeOptions`,
    :class:`~jointid.config.options.IdentifyOptions` ...), built once from the config at the edge.
__main__
    The command line ``python -m jointid.config check|reference|hash``.
"""

from __future__ import annotations

from jointid.config.datasets import dataset_folder, registered_datasets
from jointid.config.hashing import ConfigStamp, config_hash
from jointid.config.load import check_config, load_config, section
from jointid.config.reference import config_reference_markdown
from jointid.config.rig import MAX_NODES, estimate_node_count
from jointid.config.schema import SCHEMA_ENV, find_schema, load_schema
from jointid.yamlio import number_from_text

__all__ = [
    "ConfigStamp",
    "MAX_NODES",
    "SCHEMA_ENV",
    "check_config",
    "config_hash",
    "config_reference_markdown",
    "dataset_folder",
    "estimate_node_count",
    "find_schema",
    "load_config",
    "load_schema",
    "number_from_text",
    "registered_datasets",
    "section",
]

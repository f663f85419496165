"""Tests of the configuration layer (jointid.config + its schema src/jointid/config/schema.yaml)."""

from __future__ import annotations

import copy
import random
import re
import subprocess
import sys
from pathlib import Path

import jsonschema
import pytest

from jointid.config import (
    MAX_NODES,
    SCHEMA_ENV,
    check_config,
    config_hash,
    config_reference_markdown,
    estimate_node_count,
    find_schema,
    load_config,
    load_schema,
    section,
)
from jointid.errors import ConfigError

REPO = Path(__file__).resolve().parents[1]
CONFIG = REPO / "config.yaml"
SCHEMA = REPO / "src" / "jointid" / "config" / "schema.yaml"
DOC = REPO / "docs" / "config-reference.md"


UNITS = (("_kg_per_m3", "kg/m^3"), ("_N_per_m3", "N/m^3"), ("_N_per_m", "N/m"), ("_per_s", "1/s"),
         ("_pct", "percent"), ("_Hz", "Hz"), ("_Pa", "Pa"), ("_kg", "kg"), ("_N", "N"), ("_m", "m"), ("_s", "s"))


@pytest.fixture(scope="module")
def default() -> dict:
    """The default configuration: the schema defaults (the paper's rig, Cheng et al. 2019).

    Taken from the schema rather than config.yaml, so that editing config.yaml cannot break the
    exact-message tests below.
    """
    return load_config({})


def problems_of(cfg: dict) -> list[str]:
    with pytest.raises(ConfigError) as info:
        load_config(cfg)
    return info.value.problems


def modified(default: dict, change) -> dict:
    cfg = copy.deepcopy(default)
    change(cfg)
    return cfg


# ------------------------------------------------------------------------------ defaults, schema
def leaf_keys(cfg, prefix=""):
    for key, value in cfg.items():
        if isinstance(value, dict) and value:
            yield from leaf_keys(value, f"{prefix}{key}.")
        else:
            yield f"{prefix}{key}"


def test_shipped_config_yaml_validates():
    cfg = load_config(CONFIG)
    assert cfg["mesh"]["element"] in ("hex1", "hex2")
    # every parameter bound is a float, not the text a YAML 1.1 reader makes of '1.0e11'
    for p in cfg["joints"]["parameters"].values():
        assert isinstance(p["lower"], float) and isinstance(p["upper"], float)
    assert check_config(cfg)[1] == []
    # every key of config.yaml is documented
    text = DOC.read_text(encoding="utf-8")
    for key in leaf_keys(cfg):
        parts = key.split(".")
        if parts[0] in ("materials", "states", "datasets", "effects") and len(parts) > 1:
            parts[1] = "<name>"
        if parts[:2] in (["joints", "parameters"], ["joints", "fixed"], ["catalogue", "classes"]) and len(parts) > 2:
            parts[2] = "<name>"
        if parts[0] == "hypotheses" and len(parts) > 1:
            parts[1] = "<name>"
            if len(parts) > 3 and parts[2] in ("overrides", "effects"):
                parts = parts[:3]  # free-form: config sections and effects, documented where they live
            elif len(parts) > 3 and parts[2] == "fixed":
                parts[3] = "<name>"
        assert f"`{'.'.join(parts)}`" in text, key


def test_default_config_is_the_paper_rig(default):
    assert check_config(default)[1] == []
    assert default["materials"]["steel"] == {"youngs_modulus_Pa": 2.06e11, "poisson_ratio": 0.3,
                                             "density_kg_per_m3": 7850.0}
    assert default["rig"]["carriages"]["length_m"] == 0.084 and default["rig"]["table"]["position_m"] == 0.0
    assert default["joints"]["parameters"]["k_normal_N_per_m3"] == {"direction": "y", "lower": 2e11, "upper": 4e12}
    assert list(default["joints"]["parameters"]) == ["k_normal_N_per_m3", "k_lateral_N_per_m3", "k_feed_N_per_m3"]
    assert default["harmonic"]["damping"] == {"model": "modal", "damping_ratio": 0.03,
                                              "damping_ratio_range": [0.02, 0.05]}
    assert default["datasets"] == {} and default["effects"] == {} and default["report"] == {}


def test_schema_defaults_match_config_yaml(default):
    """The documented defaults are those of the shipped config.yaml (keeps the reference honest)."""
    shipped = load_config(CONFIG)
    # rig-specific by nature: the paper's rig's hypotheses (a config for another machine starts from
    # none; docs/config-reference.md says so)
    rig_specific = ("hypotheses", "catalogue")  # and the catalogue of the rig's guide block
    differing = sorted(k for k in set(leaf_keys(shipped)) | set(leaf_keys(default))
                       if section_or_none(shipped, k) != section_or_none(default, k)
                       and not k.startswith(rig_specific))
    assert differing == [], (
        f"config.yaml and the schema defaults differ at {differing}: update `default:` in "
        "src/jointid/config/schema.yaml and regenerate docs/config-reference.md"
    )


def section_or_none(cfg, dotted):
    try:
        return section(cfg, dotted)
    except ConfigError:
        return None


def test_damping_models_match_damping_module():
    from jointid.response.damping import DAMPING_MODELS

    schema = load_schema(SCHEMA)
    damping = schema["properties"]["harmonic"]["properties"]["damping"]
    assert tuple(damping["properties"]["model"]["enum"]) == tuple(DAMPING_MODELS)


def test_schema_is_valid_and_complete():
    schema = load_schema(SCHEMA)
    jsonschema.Draft202012Validator.check_schema(schema)
    # optional (absent unless given); damping_ratio has a model-dependent default (if/then); a catalogue
    # class without lateral_N_per_um is compared laterally with its normal_N_per_um; the ema section is
    # absent unless given (its keys have defaults), so the paper's configuration and its hash stay as they were
    optional_without_default = {"alpha_per_s", "beta_s", "joint_loss_factor_s", "dataset", "damping_ratio",
                                "lateral_N_per_um", "ema"}
    missing = []

    def walk(node, path, required):
        if "type" not in node or "description" not in node:
            missing.append(f"{path}: type/description")
        leaf = path.rsplit(".", 1)[-1]
        if node.get("type") == "number" and leaf != "<name>":
            symbol = next((sym for suffix, sym in UNITS if leaf.endswith(suffix)), None)
            if symbol is not None:  # the description states the unit of the key name
                assert re.search(rf"(^|[\s(,]){re.escape(symbol)}([.;,)]|$)", node["description"]), path
        if not required and "default" not in node and path.rsplit(".", 1)[-1] not in optional_without_default:
            missing.append(f"{path}: default")
        if node.get("type") == "object":
            extra = node.get("additionalProperties", True)
            if "properties" in node:
                assert extra is False, f"{path}: additionalProperties must be false"
            req = set(node.get("required", []))
            for key, sub in node.get("properties", {}).items():
                walk(sub, f"{path}.{key}", key in req)
            if isinstance(extra, dict) and "type" in extra:
                walk(extra, f"{path}.<name>", True)

    for key, sub in schema["properties"].items():
        walk(sub, key, False)
    assert missing == []
    assert schema["additionalProperties"] is False


def test_snakemake_validate_accepts_default_and_fills_same_defaults(default):
    from snakemake.utils import validate

    validate(copy.deepcopy(default), str(SCHEMA))
    partial = {"mesh": {"refine": 2}}
    validate(partial, str(SCHEMA))
    assert partial == load_config({"mesh": {"refine": 2}})


def test_yaml_1_1_numbers_from_snakemake_are_accepted(default):
    raw = copy.deepcopy(default)
    raw["materials"]["steel"]["youngs_modulus_Pa"] = "2.06e11"  # what Snakemake's YAML reader gives
    raw["joints"]["parameters"]["k_normal_N_per_m3"]["lower"] = "2.0e11"
    cfg = load_config(raw)
    assert cfg == default


def test_yaml_file_exponents_duplicates_and_syntax(tmp_path):
    good = tmp_path / "c.yaml"
    good.write_text("mesh: {max_cell_size_m: 4e-2, refine: 2.0}\nrig:\n  support: {k_mount_N_per_m: 3.0e8}\n")
    cfg = load_config(good)
    assert cfg["mesh"]["max_cell_size_m"] == 0.04 and cfg["mesh"]["refine"] == 2
    assert isinstance(cfg["mesh"]["refine"], int)
    assert cfg["rig"]["support"]["k_mount_N_per_m"] == 3.0e8

    dup = tmp_path / "dup.yaml"
    dup.write_text("mesh: {refine: 1}\ndoe: {seed: 1}\nmesh: {refine: 2}\n")
    with pytest.raises(ConfigError) as info:
        load_config(dup)
    assert info.value.problems == [
        f"{dup}:3: mesh: duplicate key — keep only one (YAML would silently use the last)"
    ]

    bad = tmp_path / "bad.yaml"
    bad.write_text("mesh:\n  refine: [1, 2\n")
    with pytest.raises(ConfigError) as info:
        load_config(bad)
    (line,) = info.value.problems
    assert line.startswith(f"{bad}:") and "YAML syntax error" in line and " — " in line

    with pytest.raises(ConfigError, match="file not found"):
        load_config(tmp_path / "missing.yaml")


# ---------------------------------------------------------------------------- one problem each
BAD = [
    # (id, change, exact line after 'config.yaml: ')
    ("misspelt key", lambda c: c["mesh"].update(elemnt=c["mesh"].pop("element")),
     "mesh.elemnt: unknown key — did you mean 'element'? (allowed: element, max_cell_size_m, height_cell_fraction, joint_cell_fraction, refine, edge_refine_levels, extrapolate_edges, edge_ratio)"),
    ("negative length", lambda c: c["rig"]["base"].update(length_m=-1.1),
     "rig.base.length_m: -1.1 must be > 0 — give the base length in metres"),
    ("inverted bounds", lambda c: c["joints"]["parameters"]["k_normal_N_per_m3"].update(lower=2e12, upper=1e11),
     "joints.parameters.k_normal_N_per_m3: lower 2e12 >= upper 1e11 — bounds are inverted; swap them"),
    ("band order", lambda c: c["harmonic"].update(band_Hz=[3500.0, 300.0]),
     "harmonic.band_Hz: [3500, 300] is not increasing — write [low, high]"),
    ("unknown material", lambda c: c["rig"]["base"].update(material="stel"),
     "rig.base.material: 'stel' is not in materials — did you mean 'steel'?"),
    ("enum", lambda c: c["mesh"].update(element="hex3"),
     "mesh.element: 'hex3' is not allowed — did you mean 'hex2'? (allowed: hex2, hex1)"),
    ("support enum", lambda c: c["rig"]["support"].update(kind="clamp"),
     "rig.support.kind: 'clamp' is not allowed — did you mean 'clamped'? (allowed: mounts, clamped, free)"),
    ("type", lambda c: c["rig"]["base"].update(length_m="long"),
     "rig.base.length_m: 'long' is text, expected a number — give the base length in metres"),
    ("true/false as text (snakemake --config)", lambda c: c["doe"]["zoom"].update(enabled="true"),
     "doe.zoom.enabled: 'true' is text, expected true or false — see docs/config-reference.md for enabled "
     "(snakemake --config passes the values inside a mapping as text: give this one in a config file added "
     "with --configfile)"),
    ("integer", lambda c: c["rig"]["motors"].update(count=2.5),
     "rig.motors.count: 2.5 is a number, expected a whole number — give the number of motors as a whole number >= 0"),
    ("poisson", lambda c: c["materials"]["steel"].update(poisson_ratio=0.5),
     "materials.steel.poisson_ratio: 0.5 must be < 0.5 — give the Poisson's ratio (> 0 and < 0.5)"),
    ("required", lambda c: c["materials"]["steel"].pop("density_kg_per_m3"),
     "materials.steel.density_kg_per_m3: missing — add it: the density in kg/m^3, > 0"),
    ("parameter name", lambda c: c["joints"]["parameters"].update(
        k_Normal=c["joints"]["parameters"].pop("k_normal_N_per_m3")),
     "joints.parameters.k_Normal: name does not match ^k_[a-z]+_N_per_m3$ — rename it: "
     "k_<word>_N_per_m3 with a lower-case word, e.g. k_normal_N_per_m3"),
    ("state force", lambda c: c["states"]["power_on"].update(em_force_N=-1.0),
     "states.power_on.em_force_N: -1 must be >= 0 — give the electromagnetic attraction force in newtons"),
    ("drive point", lambda c: c["harmonic"].update(drive_point="T19"),
     "harmonic.drive_point: 'T19' is not a valid measuring-point name (T01..T18 on the table, "
     "B01..B18 on the base) — fix the name, e.g. 'T05'"),
    ("band length", lambda c: c["harmonic"].update(band_Hz=[300.0]),
     "harmonic.band_Hz: [300] has 1 item, needs exactly 2 — give the frequency band [low, high] as a "
     "list in hertz, e.g. [300, 3500]"),
    ("damping ratio", lambda c: c["harmonic"]["damping"].update(damping_ratio=1.5),
     "harmonic.damping.damping_ratio: 1.5 must be < 1 — give the modal damping ratio (> 0 and < 1)"),
    ("rayleigh needs alpha", lambda c: c["harmonic"].update(damping={"model": "rayleigh", "beta_s": 1e-6}),
     "harmonic.damping.alpha_per_s: missing for model 'rayleigh' — add alpha_per_s: the mass-proportional "
     "Rayleigh coefficient in 1/s, >= 0"),
    ("field of another damping model", lambda c: c["harmonic"]["damping"].update(joint_loss_factor_s=1e-5),
     "harmonic.damping.joint_loss_factor_s: is set but model is 'modal' — remove it, or set model: joint; "
     "to switch the model in a config file merged after the one that sets it, write joint_loss_factor_s: null there"),
    ("carriage below rail top", lambda c: c["rig"]["carriages"].update(height_m=0.02),
     "rig.carriages.height_m: 0.02 does not reach above the rail top (0.022 above the base) — carriage height "
     "is measured from the base top; make it larger than rails.height_m"),
    ("flank band below carriage", lambda c: c["rig"]["carriages"].update(flank_contact_height_m=0.02),
     "rig.carriages.flank_contact_height_m: flank contact 0.02 + ground clearance 0.004 = 0.024 exceeds the "
     "rail height 0.022 — the contact band must lie on the rail flank; reduce one of them"),
    ("mount pads overlap", lambda c: c["rig"]["support"].update(kind="mounts", mount_inset_m=0.2),
     "rig.support.mount_inset_m: inset 0.2 + half the mount size 0.03 = 0.23 exceeds half the smaller base "
     "side (0.225) — the four mount pads would overlap; reduce mount_inset_m or mount_size_m"),
    ("motor patch off table", lambda c: c["rig"]["motors"].update(patch_length_m=0.4),
     "rig.motors.patch_length_m: 0.4 exceeds the table length 0.32 — the motor mass is spread under the "
     "table; use patch_length_m <= table.length_m"),
    ("n_verification", lambda c: c["doe"].update(n_verification=0),
     "doe.n_verification: 0 must be >= 1 — give the number of verification points as a whole number >= 1"),
    ("lhs too small", lambda c: c["doe"].update(design="lhs", n_samples=19),
     "doe.n_samples: 19 is too few for lhs: a quadratic surface in 3 parameters has 10 coefficients — "
     "use n_samples >= 20 (twice that) or design: ccf"),
    ("box-behnken k=2", lambda c: (c["doe"].update(design="box_behnken"),
                                   c["joints"]["parameters"].pop("k_feed_N_per_m3")),
     "doe.design: box_behnken needs at least 3 identified parameters, joints.parameters has 2 — use design: ccf"),
    ("rails longer than base", lambda c: c["rig"]["rails"].update(length_m=1.2),
     "rig.rails.length_m: 1.2 is longer than the base (1.1 m) — shorten the rails or lengthen the base"),
    ("carriages off table", lambda c: c["rig"]["carriages"].update(pitch_m=0.25),
     "rig.carriages.pitch_m: pitch 0.25 + carriage length 0.084 = 0.334 exceeds the table length 0.32 — "
     "the carriages must fit under the table; reduce pitch_m or lengthen the table"),
    ("carriages too wide", lambda c: c["rig"]["table"].update(width_m=0.24),
     "rig.rails.spacing_m: spacing 0.2 + carriage width 0.048 = 0.248 exceeds the table width 0.24 — "
     "the carriages must fit under the table; reduce spacing_m or widen the table"),
    ("table off rails", lambda c: c["rig"]["table"].update(position_m=-0.4),
     "rig.table.position_m: -0.4 moves the carriages off the rails — keep |position_m| <= 0.348 "
     "(half rail length minus half the carriage span)"),
    ("tiny mesh", lambda c: c["mesh"].update(max_cell_size_m=0.0004),
     "mesh.max_cell_size_m: 0.0004 is too small (with refine: 1): about 1.1e10 nodes, above the limit of 2e6 — "
     "use max_cell_size_m >= 0.0073 with refine: 1"),
    ("unknown dataset state", lambda c: c.update(datasets={"rig2": {"path": "data/rig2", "states": ["power_onn"]}}),
     "datasets.rig2.states[0]: 'power_onn' is not in states — did you mean 'power_on'?"),
    ("free and zero shift", lambda c: (c["rig"]["support"].update(kind="free"), c["solver"].update(shift_Hz=0.0)),
     "solver.shift_Hz: 0 with rig.support.kind: free factorises a singular stiffness (rigid-body modes) — "
     "use a negative shift, e.g. -10"),
    ("unknown top-level key", lambda c: c.update(reprot={}),
     "reprot: unknown key — did you mean 'report'? (allowed: run, materials, model, rig, mesh, mesh_check, carriage_rigidity, catalogue, joints, states, measurements, "
     "datasets, doe, surface, identify, solver, harmonic, diagnosis, effects, linked, hypotheses, ema, next_measurement, report)"),
    ("length in mm", lambda c: c["rig"]["base"].update(length_m=1100),
     "rig.base.length_m: 1100 m is not a plausible size of a machine-tool feed drive; the value looks like mm — "
     "write 1.1 (the unit of every *_m key is m)"),
    ("non-finite", lambda c: c["rig"]["base"].update(width_m=float("inf")),
     "rig.base.width_m: inf is not a finite number — give a finite value"),
]


@pytest.mark.parametrize("change, line", [b[1:] for b in BAD], ids=[b[0] for b in BAD])
def test_each_bad_config_gives_exactly_the_promised_line(default, change, line):
    problems = problems_of(modified(default, change))
    assert problems == [f"config.yaml: {line}"]


def test_problem_lines_have_where_what_fix_and_no_dump(default):
    for _, change, _ in BAD:
        for line in problems_of(modified(default, change)):
            assert line.startswith("config.yaml: ")
            assert line.count(" — ") == 1
            assert "Traceback" not in line and "Failed validating" not in line and "\n" not in line


def test_several_problems_reported_together(default):
    def change(c):
        c["mesh"]["elemnt"] = c["mesh"].pop("element")
        c["rig"]["base"]["length_m"] = -1.1
        c["rig"]["table"]["material"] = "alu"  # unique prefix of 'aluminium'
        c["harmonic"]["band_Hz"] = [3500.0, 300.0]
        c["joints"]["parameters"]["k_lateral_N_per_m3"].update(lower=2e12, upper=1e11)

    problems = problems_of(modified(default, change))
    assert len(problems) == 5
    text = "\n".join(problems)
    for key in ("mesh.elemnt:", "rig.base.length_m:", "rig.table.material:", "harmonic.band_Hz:",
                "joints.parameters.k_lateral_N_per_m3:"):
        assert f"config.yaml: {key}" in text
    assert "did you mean 'aluminium'?" in text
    # the invalid base length must not produce follow-up geometry complaints
    assert "rails.length_m" not in text


def test_semantic_checks_skip_keys_already_invalid(default):
    problems = problems_of(modified(default, lambda c: c["rig"]["rails"].update(length_m="long")))
    assert problems == ["config.yaml: rig.rails.length_m: 'long' is text, expected a number — "
                        "give the rail length in metres"]


def test_doe_size_limits(default):
    load_config(modified(default, lambda c: c["doe"].update(design="lhs", n_samples=20)))  # k = 3
    two = modified(default, lambda c: c["joints"]["parameters"].pop("k_feed_N_per_m3"))
    load_config(modified(two, lambda c: c["doe"].update(design="lhs", n_samples=12)))  # k = 2: 2 * 6
    assert "doe.n_samples: 11 is too few" in problems_of(
        modified(two, lambda c: c["doe"].update(design="lhs", n_samples=11)))[0]
    load_config(modified(default, lambda c: c["doe"].update(design="box_behnken")))  # k = 3
    assert problems_of(modified(default, lambda c: c["doe"].update(design="box_behnken", n_center=0))) == [
        "config.yaml: doe.n_center: 0 with design box_behnken leaves the quadratic surface undetermined — "
        "use n_center >= 1"]
    load_config(modified(default, lambda c: c["doe"].update(n_center=0)))  # ccf, k = 3: 14 points >= 10
    one = modified(two, lambda c: c["joints"]["parameters"].pop("k_lateral_N_per_m3"))
    assert problems_of(modified(one, lambda c: c["doe"].update(n_center=0))) == [
        "config.yaml: doe.n_center: 0 with design ccf and 1 parameter gives only 2 distinct points for 3 "
        "coefficients — use n_center >= 1"]


def test_optional_sections_are_accepted(default):
    def change(c):
        c["datasets"] = {"rig2": {"path": "data/rig2", "states": ["power_on"]}}
        c["effects"] = {"em_force": {"values_N": [0, 500, 1000], "anything": {"free": True}}}
        c["report"] = {"title": "x", "figures": ["frf"]}
        c["states"]["power_on"]["dataset"] = "rig2"
        c["harmonic"]["damping"] = {"model": "joint", "joint_loss_factor_s": 1e-5}

    cfg = load_config(modified(default, change))
    assert cfg["effects"]["em_force"]["anything"] == {"free": True}


# ------------------------------------------------------------------------------------ overrides
def test_overrides_dotted_nested_and_strings(default):
    cfg = load_config(CONFIG, overrides={"mesh.refine": 2, "harmonic": {"damping": {"damping_ratio": 0.02}}})
    assert cfg["mesh"]["refine"] == 2 and cfg["harmonic"]["damping"]["damping_ratio"] == 0.02
    assert cfg["harmonic"]["damping"]["model"] == "modal"  # deep merge keeps siblings
    cfg = load_config(CONFIG, overrides=["doe.design=lhs", "doe.n_samples=20", "harmonic.band_Hz=[100, 2e3]"])
    assert cfg["doe"]["n_samples"] == 20 and cfg["harmonic"]["band_Hz"] == [100.0, 2000.0]
    with pytest.raises(ConfigError) as info:
        load_config(CONFIG, overrides=["mesh.refin=2"])
    assert info.value.problems == [
        f"{CONFIG}: mesh.refin: unknown key — did you mean 'refine'? (allowed: element, max_cell_size_m, height_cell_fraction, joint_cell_fraction, refine, edge_refine_levels, extrapolate_edges, edge_ratio)"
    ]


def test_input_mapping_not_modified(default):
    raw = {"mesh": {"refine": 1}}
    load_config(raw)
    assert raw == {"mesh": {"refine": 1}}


# ------------------------------------------------------------------------------- hash, section
def test_config_hash_stable_across_key_order_and_sensitive_to_values(default):
    h = config_hash(default)
    assert len(h) == 12 and int(h, 16) >= 0

    def shuffled(obj, rng):
        if isinstance(obj, dict):
            items = list(obj.items())
            rng.shuffle(items)
            return {k: shuffled(v, rng) for k, v in items}
        return obj

    rng = random.Random(0)
    for _ in range(5):
        assert config_hash(shuffled(default, rng)) == h
    changed = modified(default, lambda c: c["mesh"].update(refine=2))
    assert config_hash(changed) != h
    # only the hashed sections matter
    assert config_hash(changed, ["rig", "joints.parameters"]) == config_hash(default, ["rig", "joints.parameters"])
    assert config_hash(changed, "mesh") != config_hash(default, "mesh")
    # int and float of the same value hash alike
    assert config_hash({"a": 1}) == config_hash({"a": 1.0})
    assert config_hash({"a": [1, 2]}) != config_hash({"a": [2, 1]})


def test_section_returns_deep_copy(default):
    base = section(default, "rig", "base")
    assert base == section(default, "rig.base") == default["rig"]["base"]
    base["length_m"] = 9.0
    assert default["rig"]["base"]["length_m"] == 1.1
    with pytest.raises(ConfigError, match="did you mean 'base'"):
        section(default, "rig.bsae")


# ----------------------------------------------------------------------------------- mesh size
def test_node_estimate_matches_hand_count(default):
    # hex2, h = 0.04 m (0.02 m along Y): nodes per part = prod(2 * ceil(extent / h) + 1)
    base = 25 * 9 * 57          # 0.45 x 0.08 x 1.10
    rail = 3 * 5 * 51           # 0.023 x 0.022 x 1.00
    carriage = 5 * 5 * 7        # 0.048 x 0.036 x 0.084
    table = 17 * 5 * 17         # 0.32 x 0.035 x 0.32
    default = modified(default, lambda c: c["mesh"].update(max_cell_size_m=0.04))
    assert estimate_node_count(default) == base + 2 * rail + 4 * carriage + table
    hex1 = modified(default, lambda c: c["mesh"].update(element="hex1"))
    assert estimate_node_count(hex1) == 13 * 5 * 29 + 2 * 2 * 3 * 26 + 4 * 3 * 3 * 4 + 9 * 3 * 9


def test_suggested_cell_size_passes(default):
    line = problems_of(modified(default, lambda c: c["mesh"].update(max_cell_size_m=0.0004)))[0]
    suggested = float(line.rsplit(">= ", 1)[1].split()[0])
    ok = modified(default, lambda c: c["mesh"].update(max_cell_size_m=suggested))
    assert estimate_node_count(ok) <= MAX_NODES
    load_config(ok)


# ------------------------------------------------------------------------------- schema lookup
def test_schema_found_from_elsewhere_and_env_override(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    monkeypatch.delenv(SCHEMA_ENV, raising=False)
    assert find_schema() == SCHEMA.resolve()  # via the package location
    monkeypatch.setenv(SCHEMA_ENV, str(tmp_path / "nope.yaml"))
    with pytest.raises(ConfigError) as info:
        find_schema()
    (line,) = info.value.problems
    assert line.startswith(f"{SCHEMA_ENV}=") and "schema file not found" in line


def test_other_projects_schema_is_ignored(tmp_path, monkeypatch):
    other = tmp_path / "workflow" / "schemas"
    other.mkdir(parents=True)
    (other / "config.schema.yaml").write_text("title: someone else's workflow\ntype: object\n")
    monkeypatch.chdir(tmp_path)
    monkeypatch.delenv(SCHEMA_ENV, raising=False)
    assert find_schema() == SCHEMA.resolve()


# ------------------------------------------------------------------------------------------ CLI
def run_cli(*args, cwd):
    return subprocess.run([sys.executable, "-m", "jointid.config", *args], cwd=cwd,
                          capture_output=True, text=True, timeout=60)


def test_cli_check_ok_and_bad(tmp_path):
    ok = run_cli("check", str(CONFIG), cwd=REPO)
    assert ok.returncode == 0 and ok.stdout.strip() == f"{CONFIG}: OK"

    bad = tmp_path / "config.yaml"
    bad.write_text(CONFIG.read_text().replace("length_m: 1.10", "length_m: -1.1"))
    (tmp_path / "data").symlink_to(REPO / "data")  # the check also looks for the dataset folder
    res = run_cli("check", "config.yaml", cwd=tmp_path)
    assert res.returncode == 1
    assert res.stderr.strip().splitlines() == [
        "config.yaml: rig.base.length_m: -1.1 must be > 0 — give the base length in metres"
    ]
    assert "Traceback" not in res.stderr + res.stdout

    missing = run_cli("check", "absent.yaml", cwd=tmp_path)
    assert missing.returncode == 1 and "Traceback" not in missing.stderr
    assert missing.stderr.startswith("absent.yaml: file not found")


# ----------------------------------------------------------------------------------------- docs
def test_committed_reference_equals_generated():
    generated = config_reference_markdown(load_schema(SCHEMA))
    assert DOC.read_text(encoding="utf-8") == generated, (
        "docs/config-reference.md is stale: run "
        "`python -m jointid.config reference --output docs/config-reference.md`"
    )


def test_reference_lists_every_leaf_key():
    text = config_reference_markdown(load_schema(SCHEMA))
    for key in ("rig.base.length_m", "joints.parameters.<name>.lower", "harmonic.damping.joint_loss_factor_s",
                "states.<name>.dataset", "datasets.<name>.states", "mesh.refine", "report"):
        assert f"| `{key}` |" in text


# ------------------------------------------------------------------- numbers given as text
def test_number_from_text_is_the_shared_rule():
    from jointid.config import number_from_text

    for text, value in (("1e3", 1000.0), ("2.0e8", 2.0e8), ("-1E-6", -1e-6), (" .5 ", 0.5), ("7", 7.0), ("3.", 3.0)):
        assert number_from_text(text) == value
    for other in ("one", "1e3 N", "1,5", "inf", "nan", "", "0x10", 1000.0, None, True):
        assert number_from_text(other) is None


# --------------------------------------------------------------- null removes a key (overlays)
RAYLEIGH = {"model": "rayleigh", "alpha_per_s": 10, "beta_s": "1e-6"}  # beta as Snakemake's YAML 1.1 reads it


def test_overlay_switches_damping_model_with_null():
    cfg = load_config(CONFIG, overrides={"harmonic": {"damping": {**RAYLEIGH, "damping_ratio": None}}})
    assert cfg["harmonic"]["damping"] == {"model": "rayleigh", "alpha_per_s": 10.0, "beta_s": 1e-6,
                                          "damping_ratio_range": [0.02, 0.05]}
    # the same from --set strings: an empty value is null
    cfg = load_config(CONFIG, overrides=["harmonic.damping.model=rayleigh", "harmonic.damping.alpha_per_s=10",
                                         "harmonic.damping.beta_s=1e-6", "harmonic.damping.damping_ratio="])
    assert cfg["harmonic"]["damping"] == {"model": "rayleigh", "alpha_per_s": 10.0, "beta_s": 1e-6,
                                          "damping_ratio_range": [0.02, 0.05]}


def test_overlay_without_null_says_how_to_switch():
    with pytest.raises(ConfigError) as info:
        load_config(CONFIG, overrides={"harmonic": {"damping": RAYLEIGH}})
    assert info.value.problems == [
        f"{CONFIG}: harmonic.damping.damping_ratio: is set but model is 'rayleigh' — remove it, or set model: "
        "modal; to switch the model in a config file merged after the one that sets it, write damping_ratio: null there"]


def test_snakemake_merge_of_configfiles_gives_the_same(tmp_path, monkeypatch):
    """`snakemake --configfile config.yaml mine.yaml`: Snakemake merges the files (deeply, null kept)
    before jointid.config.snakefile.validated sees them."""
    from snakemake.common.configfile import load_configfile
    from snakemake.utils import update_config

    from jointid.config.snakefile import validated

    monkeypatch.chdir(REPO)  # validated() checks the dataset folders relative to the working directory
    mine = tmp_path / "mine.yaml"
    mine.write_text("harmonic: {damping: {model: rayleigh, alpha_per_s: 10, beta_s: 1e-6, damping_ratio: null}}\n")
    config = load_configfile(str(CONFIG))
    update_config(config, load_configfile(str(mine)))
    assert config["harmonic"]["damping"]["damping_ratio"] is None
    cfg = validated(config)
    assert cfg["harmonic"]["damping"] == {"model": "rayleigh", "alpha_per_s": 10.0, "beta_s": 1e-6,
                                          "damping_ratio_range": [0.02, 0.05]}
    assert cfg == load_config(CONFIG, overrides={"harmonic": {"damping": {**RAYLEIGH, "damping_ratio": None}}})


def test_null_means_default_but_unknown_and_required_keys_are_still_reported(default):
    cfg = load_config({"mesh": {"refine": None}, "harmonic": {"damping": {"model": None}}, "datasets": None})
    assert cfg["mesh"]["refine"] == 1 and cfg["datasets"] == {}
    assert cfg["harmonic"]["damping"] == {"model": "modal", "damping_ratio": 0.03,
                                          "damping_ratio_range": [0.02, 0.05]}
    # a state removed by an overlay
    cfg = load_config(CONFIG, overrides={"states": {"power_on": None}})
    assert list(cfg["states"]) == ["power_off"]
    assert problems_of({"mesh": {"refin": None}})[0].startswith("config.yaml: mesh.refin: unknown key")
    assert problems_of({"states": {"s1": {"em_force_N": None}}}) == [
        "config.yaml: states.s1.em_force_N: missing — add it: the electromagnetic attraction force in newtons, >= 0"]


# --------------------------------------------------------------------------- dataset folders
MODES = "state,mode,freq_Hz\npower_off,1,344.3\npower_on,1,350.0\n"


@pytest.fixture
def workdir(tmp_path, monkeypatch):
    """A working directory with data/paper (the default dataset) and data/rig2 (power_on only)."""
    (tmp_path / "data").mkdir()
    (tmp_path / "data" / "paper").symlink_to(REPO / "data" / "paper")
    (tmp_path / "data" / "rig2").mkdir()
    (tmp_path / "data" / "rig2" / "modes.csv").write_text("state,mode,freq_Hz\npower_on,1,350.0\n")
    (tmp_path / "data" / "rig2" / "conditions.yaml").write_text(
        "source: test rig 2\nstates:\n  power_on: {em_force_N: 1000.0}\n")
    monkeypatch.chdir(tmp_path)
    return tmp_path


def dataset_problems(cfg: dict) -> list[str]:
    with pytest.raises(ConfigError) as info:
        load_config(cfg, check_datasets=True)
    return info.value.problems


def test_datasets_that_resolve_pass(default, workdir):
    load_config(default, check_datasets=True)
    by_name = modified(default, lambda c: (c.update(datasets={"rig2": {"path": "data/rig2", "states": ["power_on"]}}),
                                           c["states"]["power_on"].update(dataset="rig2")))
    assert load_config(by_name, check_datasets=True)["states"]["power_on"]["dataset"] == "rig2"
    load_config(modified(default, lambda c: c["states"]["power_on"].update(dataset="data/rig2")), check_datasets=True)
    # every state has its own dataset: measurements.dataset is not read, so it need not exist
    own = modified(default, lambda c: (c["states"]["power_on"].update(dataset="data/paper"),
                                       c["states"]["power_off"].update(dataset="data/paper"),
                                       c["measurements"].update(dataset="data/none")))
    load_config(own, check_datasets=True)


def test_a_broken_dataset_is_reported_at_config_load_naming_file_and_fix(default, workdir):
    """Frequencies in kHz and a missing conditions.yaml stop the run before any job (the Snakefile
    validates with check_datasets), one line each, naming the config key, the file and the fix."""
    (workdir / "data" / "rig2" / "modes.csv").write_text("state,mode,freq_Hz\npower_on,1,0.35\npower_on,2,1.3\n")
    (workdir / "data" / "rig2" / "conditions.yaml").unlink()
    cfg = modified(default, lambda c: c["states"]["power_on"].update(dataset="data/rig2"))
    lines = dataset_problems(cfg)
    assert len(lines) == 2, lines
    assert all(line.startswith("config.yaml: states.power_on.dataset: the dataset has a problem: data/rig2/")
               for line in lines)
    assert any("modes.csv" in line and "kHz" in line for line in lines)
    assert any("conditions.yaml" in line and "file is missing" in line for line in lines)


BROKEN_DATASETS = [  # (case, modes.csv text, keep conditions.yaml, what the line must say)
    ("frequencies in kHz", "state,mode,freq_Hz\npower_on,1,0.35\npower_on,2,1.3\n", True,
     "multiply all frequencies by 1000"),
    ("a freq_kHz column", "state,mode,freq_kHz\npower_on,1,0.35\n", True, "rename the column to freq_Hz"),
    ("; and decimal commas", "state;mode;freq_Hz\npower_on;1;350,5\n", True, "';'"),
    ("damping in percent", "state,mode,freq_Hz,damping_ratio\npower_on,1,350.0,3.0\n", True, "damping_ratio"),
    ("no conditions.yaml", "state,mode,freq_Hz\npower_on,1,350.0\n", False, "conditions.yaml: file is missing"),
]


@pytest.mark.parametrize("case, modes, conditions, says", BROKEN_DATASETS, ids=[b[0] for b in BROKEN_DATASETS])
def test_every_broken_dataset_case_stops_the_config_check(default, workdir, case, modes, conditions, says):
    """The mis-unit and missing-file cases fail when the configuration is checked (as the Snakefile does
    before the first job), naming the config key, the file and the fix."""
    (workdir / "data" / "rig2" / "modes.csv").write_text(modes)
    if not conditions:
        (workdir / "data" / "rig2" / "conditions.yaml").unlink()
    cfg = modified(default, lambda c: c["states"]["power_on"].update(dataset="data/rig2"))
    lines = dataset_problems(cfg)
    assert any(says in line and "data/rig2/" in line for line in lines), lines
    assert all(line.startswith("config.yaml: states.power_on.dataset: ") for line in lines), lines


def test_unknown_state_dataset_is_reported_with_key_value_and_fix(default, workdir):
    cfg = modified(default, lambda c: c["states"]["power_on"].update(dataset="rig2x"))
    assert load_config(cfg)["states"]["power_on"]["dataset"] == "rig2x"  # off by default: cwd-independent
    assert dataset_problems(cfg) == [
        "config.yaml: states.power_on.dataset: 'rig2x' is neither a name in datasets nor an existing folder — "
        "register it under datasets (rig2x: {path: <folder>, states: [power_on]}) or give the path of a dataset "
        f"folder (relative to the working directory {workdir})"]
    named = modified(cfg, lambda c: c.update(datasets={"rig2": {"path": "data/rig2", "states": ["power_on"]}}))
    assert dataset_problems(named) == [
        "config.yaml: states.power_on.dataset: 'rig2x' is neither a name in datasets nor an existing folder — "
        "did you mean 'rig2'?"]


def test_registered_and_default_dataset_folders_must_exist(default, workdir):
    cfg = modified(default, lambda c: (c.update(datasets={"rig3": {"path": "data/rig3", "states": ["power_on"]}}),
                                       c["measurements"].update(dataset="data/papr")))
    assert dataset_problems(cfg) == [
        f"config.yaml: datasets.rig3.path: 'data/rig3' is not an existing folder (relative to the working directory "
        f"{workdir}) — give the folder that holds the dataset's modes.csv and conditions.yaml",
        f"config.yaml: measurements.dataset: 'data/papr' is not an existing folder (relative to the working directory "
        f"{workdir}; used by power_off, power_on) — give the folder that holds the measured modes.csv and "
        "conditions.yaml, or run from the folder it is relative to"]


def test_state_without_modes_in_its_dataset_is_reported(default, workdir):
    cfg = modified(default, lambda c: (c["states"]["power_off"].update(dataset="data/rig2"),
                                       c["states"].update(power_mid={"em_force_N": 500.0}),
                                       c.update(datasets={"rig2": {"path": "data/rig2",
                                                                   "states": ["power_on", "power_off"]}})))
    assert dataset_problems(cfg) == [
        "config.yaml: states.power_off: dataset data/rig2 has no modes of state 'power_off' in modes.csv (its states: "
        "power_on) — measure it there, or set states.power_off.dataset to a dataset that holds it",
        "config.yaml: states.power_mid: dataset data/paper has no modes of state 'power_mid' in modes.csv (its "
        "states: power_off, power_on) — measure it there, or set states.power_mid.dataset to a dataset that holds it",
        "config.yaml: datasets.rig2.states[1]: 'power_off' has no modes in data/rig2/modes.csv (its states: "
        "power_on) — remove it from the list, or add its modes"]


def test_weights_and_model_modes_are_checked_against_the_measured_modes_before_any_solve(default, workdir):
    # the paper's data measure six modes per state
    cfg = modified(default, lambda c: (c["identify"].update(weights=[1.0] * 5), c["solver"].update(n_modes=4)))
    assert dataset_problems(cfg) == [
        "config.yaml: identify.weights: 5 weights, but the datasets measure 6 modes of power_off, 6 modes of "
        "power_on — give one weight per measured mode, or [] for all 1",
        "config.yaml: solver.n_modes: 4 model modes cannot pair the 6 measured modes of power_off — use "
        "n_modes >= 6 (a few more, so that the pairing can skip modes the test did not see)"]
    load_config(modified(default, lambda c: c["identify"].update(weights=[1.0] * 6)), check_datasets=True)
    # one state from a dataset with a single mode: its count is checked on its own
    one = modified(default, lambda c: (c["states"]["power_on"].update(dataset="data/rig2"),
                                       c["identify"].update(weights=[1.0] * 6)))
    assert dataset_problems(one) == [
        "config.yaml: identify.weights: 6 weights, but the datasets measure 1 mode of power_on — give one "
        "weight per measured mode, or [] for all 1"]


def test_cli_and_snakefile_check_the_datasets(workdir, capsys):
    from jointid.config.snakefile import validated

    res = run_cli("check", str(CONFIG), "--set", "states.power_on.dataset=rig2x", cwd=workdir)
    assert res.returncode == 1 and "Traceback" not in res.stderr
    assert res.stderr.splitlines() == [
        f"{CONFIG}: states.power_on.dataset: 'rig2x' is neither a name in datasets nor an existing folder — "
        "register it under datasets (rig2x: {path: <folder>, states: [power_on]}) or give the path of a dataset "
        f"folder (relative to the working directory {workdir})"]
    raw = load_config(CONFIG)
    raw["states"]["power_on"]["dataset"] = "rig2x"
    with pytest.raises(SystemExit) as info:
        validated(raw)
    assert info.value.code == 1
    assert "config.yaml: states.power_on.dataset: 'rig2x' is neither" in capsys.readouterr().err


def test_problem_lines_name_the_config_file_that_set_the_key(tmp_path):
    """With --configfile overlays the Snakefile names the file each bad key came from (the deepest
    definition, the later file on a tie), not config.yaml for all."""
    from jointid.config.snakefile import attribute

    base, over = tmp_path / "config.yaml", tmp_path / "over.yaml"
    base.write_text("mesh: {refine: 1}\nrig: {base: {length_m: 1.1}}\n")
    over.write_text("mesh: {refine: 0}\ndoe: {seed: 1}\n")
    lines = ["config.yaml: mesh.refine: 0 must be >= 1", "config.yaml: rig.base.length_m: bad",
             "config.yaml: doe.seed: bad", "config.yaml: harmonic.band_Hz[1]: bad"]
    assert attribute(lines, [str(base), str(over)]) == [
        f"{over}: mesh.refine: 0 must be >= 1", f"{base}: rig.base.length_m: bad", f"{over}: doe.seed: bad",
        "config.yaml: harmonic.band_Hz[1]: bad"]

"""A carriage's identified rigidity against its guide catalogue (config section ``catalogue``).

The comparison (jointid.response.carriage.catalogue_comparison) against hand-computed numbers, its
place in carriage_rigidity.json and on the report page, and the validation of the config section.
"""

from __future__ import annotations

import copy
import json
import math

import pytest

from conftest import REPO
from jointid.config import load_config
from jointid.config.load import check_config
from jointid.config.options import CarriageOptions
from jointid.response.carriage import BlockRigidity, catalogue_comparison, catalogue_verdict

HIWIN = {"block": "HIWIN HGH25CA", "source": "HIWIN Compact, Table 1.13",
         "classes": {"Z0": {"normal_N_per_um": 520.0}, "ZA": {"normal_N_per_um": 630.0},
                     "ZB": {"normal_N_per_um": 730.0}}}
IDENTIFIED = {"normal": {"assembly_N_per_um": 1370.0, "assembly_ci95_low_N_per_um": 1200.0,
                         "assembly_ci95_high_N_per_um": 1500.0},
              "lateral": {"assembly_N_per_um": 800.0, "assembly_ci95_low_N_per_um": 700.0,
                          "assembly_ci95_high_N_per_um": 900.0},
              "feed": {"assembly_N_per_um": 27.0}}


@pytest.fixture(scope="module")
def cfg():
    return load_config(REPO / "config.yaml")


# ------------------------------------------------------------------------------------- comparison
def test_ratios_nearest_class_and_the_stiffest_by_hand():
    comp = catalogue_comparison(IDENTIFIED, HIWIN)
    assert set(comp["directions"]) == {"normal", "lateral"}  # a catalogue states no feed rigidity
    n = comp["directions"]["normal"]
    assert n["identified_N_per_um"] == 1370.0
    assert {k: c["ratio"] for k, c in n["classes"].items()} == pytest.approx(
        {"Z0": 2.6346153846, "ZA": 2.1746031746, "ZB": 1.8767123288})
    assert n["nearest_class"] == "ZB" and n["softest_class"] == "Z0" and n["stiffest_class"] == "ZB"
    assert n["exceeds_stiffest"] and not n["below_softest"]
    assert n["interval_exceeds_stiffest"]          # 1200 > 730: the whole interval is above ZB
    lat = comp["directions"]["lateral"]
    # one value per class in the catalogue: the lateral comparison uses it
    assert {c["catalogue_key"] for c in lat["classes"].values()} == {"normal_N_per_um"}
    assert lat["classes"]["ZB"]["ratio"] == pytest.approx(800 / 730)
    assert lat["exceeds_stiffest"] and not lat["interval_exceeds_stiffest"]  # 700 < 730 < 800
    assert comp["lateral_to_normal"]["identified"] == pytest.approx(800 / 1370)
    assert comp["lateral_to_normal"]["catalogue"] == {"Z0": 1.0, "ZA": 1.0, "ZB": 1.0}
    assert comp["block"] == "HIWIN HGH25CA" and comp["source"] == "HIWIN Compact, Table 1.13"


def test_nearest_is_nearest_as_a_factor_not_in_N_per_um():
    cat = {"block": "b", "source": "s", "classes": {"A": {"normal_N_per_um": 100.0},
                                                    "B": {"normal_N_per_um": 400.0}}}
    # 220: 120 N/um from A and 180 from B, but a factor 2.2 above A and only 1.82 below B
    at = lambda v: catalogue_comparison({"normal": {"assembly_N_per_um": v}}, cat)["directions"]["normal"]  # noqa: E731
    assert at(220.0)["nearest_class"] == "B"
    assert at(190.0)["nearest_class"] == "A"      # factor 1.9 above A, 2.1 below B
    assert at(200.0)["nearest_class"] in ("A", "B") and math.isclose(
        at(200.0)["classes"]["A"]["ratio"] * at(200.0)["classes"]["B"]["ratio"], 1.0)
    inside = at(190.0)
    assert not inside["exceeds_stiffest"] and not inside["below_softest"]
    assert "interval_exceeds_stiffest" not in inside  # no interval given, none claimed


def test_a_stated_lateral_value_is_used_and_below_softest_is_flagged():
    cat = {"block": "b", "source": "s",
           "classes": {"light": {"normal_N_per_um": 300.0, "lateral_N_per_um": 250.0},
                       "heavy": {"normal_N_per_um": 600.0, "lateral_N_per_um": 500.0}}}
    comp = catalogue_comparison({"normal": {"assembly_N_per_um": 450.0},
                                 "lateral": {"assembly_N_per_um": 200.0, "assembly_ci95_low_N_per_um": 150.0,
                                             "assembly_ci95_high_N_per_um": 240.0}}, cat)
    lat = comp["directions"]["lateral"]
    assert lat["classes"]["light"] == {"catalogue_N_per_um": 250.0, "catalogue_key": "lateral_N_per_um",
                                       "ratio": pytest.approx(0.8)}
    assert lat["below_softest"] and lat["interval_below_softest"] and not lat["exceeds_stiffest"]
    assert lat["nearest_class"] == "light"
    assert comp["lateral_to_normal"]["catalogue"] == {"light": pytest.approx(250 / 300),
                                                      "heavy": pytest.approx(500 / 600)}
    assert comp["directions"]["normal"]["nearest_class"] in ("light", "heavy")
    assert catalogue_verdict("lateral", lat) == "lateral 200 N/um: 0.80 x light (250), below the softest class " \
                                                "with its whole 95 % interval"


def test_verdict_lines():
    comp = catalogue_comparison(IDENTIFIED, HIWIN)["directions"]
    assert catalogue_verdict("normal", comp["normal"]) == ("normal 1,370 N/um: 1.88 x ZB (730), above the "
                                                           "stiffest class with its whole 95 % interval")
    assert catalogue_verdict("lateral", comp["lateral"]) == "lateral 800 N/um: 1.10 x ZB (730), above the stiffest class"
    mid = catalogue_comparison({"normal": {"assembly_N_per_um": 600.0}}, HIWIN)["directions"]["normal"]
    assert catalogue_verdict("normal", mid) == "normal 600 N/um: within the classes, nearest ZA (630, ratio 0.95)"


@pytest.mark.parametrize("catalogue", [None, {}, {"block": "", "source": "", "classes": {}}])
def test_no_catalogue_no_comparison(catalogue):
    assert catalogue_comparison(IDENTIFIED, catalogue) is None


# ------------------------------------------------------------------------------ stage and report
def test_stage_writes_the_comparison_of_its_assembly(cfg, tmp_path, monkeypatch):
    """carriage_rigidity.json's ``catalogue`` compares the assembly the stage computed (the FE test
    itself is replaced by fixed numbers here; tests/test_blockrigidity.py checks it)."""
    import jointid.stages.carriage as stage

    class FakeTest:
        def __init__(self, cfg, cell):
            pass

        def rigidity(self, theta, parts=True):
            f = theta["k_normal_N_per_m3"] / 3.0e11  # the interval's ends scale every direction
            return BlockRigidity({"lateral": 1.1e9 * f, "normal": 1.46e9 * f, "feed": 2.7e7 * f},
                                 {"lateral": 3.9e9, "normal": 1.49e10, "feed": 6.3e9} if parts else {}, 41000, 0.006)

    import jointid.response.carriage as block

    monkeypatch.setattr(block, "BlockTest", FakeTest)  # the stage imports it when it runs
    theta = {"k_normal_N_per_m3": 3.0e11, "k_lateral_N_per_m3": 1.3e12, "k_feed_N_per_m3": 8.4e9}
    (tmp_path / "params.json").write_text(json.dumps(
        {"parameters": {n: {"value": v, "ci95_low": 0.8 * v, "ci95_high": 1.25 * v} for n, v in theta.items()}}))
    lines = []
    doc = stage.run_carriage_rigidity(CarriageOptions.from_config(cfg), "power_on", str(tmp_path / "params.json"), str(tmp_path / "o.json"),
                                      log=lines.append)
    written = json.loads((tmp_path / "o.json").read_text())
    n = written["catalogue"]["directions"]["normal"]
    assert n["identified_N_per_um"] == pytest.approx(1460.0)
    assert (n["identified_ci95_low_N_per_um"], n["identified_ci95_high_N_per_um"]) == pytest.approx((1168.0, 1825.0))
    assert n["classes"]["ZB"] == {"catalogue_N_per_um": 730.0, "catalogue_key": "normal_N_per_um",
                                  "ratio": pytest.approx(2.0)}
    assert n["exceeds_stiffest"] and n["interval_exceeds_stiffest"]
    assert written["catalogue"]["directions"]["lateral"]["classes"]["Z0"]["ratio"] == pytest.approx(1100 / 520)
    for d in ("normal", "lateral"):  # the returned document is the written one (JSON rounds the last digits)
        got, want = written["catalogue"]["directions"][d], doc["catalogue"]["directions"][d]
        assert got["nearest_class"] == want["nearest_class"] and got.keys() == want.keys()
        assert got["classes"]["ZA"]["ratio"] == pytest.approx(want["classes"]["ZA"]["ratio"], rel=1e-9)
    assert any("normal 1,460 N/um: 2.00 x ZB (730), above the stiffest class" in x for x in lines)

    plain = copy.deepcopy(cfg)
    plain["catalogue"] = {}
    assert stage.run_carriage_rigidity(CarriageOptions.from_config(plain), "power_on", str(tmp_path / "params.json"), str(tmp_path / "p.json"),
                                       log=lambda m: None)["catalogue"] is None


def test_rule_depends_on_the_catalogue_section():
    from jointid.config.rule_keys import CARRIAGE as CONFIG

    assert "catalogue" in CONFIG  # a changed catalogue reruns carriage_rigidity (and so the report)


def test_report_table_and_figure():
    from jointid.reporting import figures as fg
    from jointid.reporting.page import _catalogue_html

    comps = {"power_off": catalogue_comparison(IDENTIFIED, HIWIN),
             "power_on": catalogue_comparison({d: {k: 1.5 * v for k, v in r.items()} for d, r in IDENTIFIED.items()},
                                              HIWIN)}
    data = {"rigidity": {s: {"state": s, "catalogue": c} for s, c in comps.items()}}
    page = _catalogue_html(data, {"catalogue": b"png"})
    assert "Against the catalogue: HIWIN HGH25CA" in page
    for head in ("identified (N/µm)", "ZB (N/µm)", "ratio to ZB", "nearest class"):
        assert head in page
    assert ">1,370<" in page and ">2,055<" in page and ">1.88<" in page and ">2.82<" in page  # 1.5 x 1370 / 730
    assert "above the stiffest" in page and "used for the lateral direction" in page
    assert "lateral / normal 0.58 (catalogue Z0 1.00, ZA 1.00, ZB 1.00)" in page
    assert "data:image/png;base64,cG5n" in page
    assert _catalogue_html({"rigidity": {"power_off": {"state": "power_off", "catalogue": None}}}) == ""
    fig = fg.catalogue_rigidity(comps)
    ax = fig.axes[0]
    assert [t.get_text() for t in ax.get_xticklabels()] == ["normal (Y)", "lateral (X)"]
    assert sorted(ax.get_legend_handles_labels()[1]) == ["power-off", "power-on"]
    assert fg.png_bytes(fig)[:8] == b"\x89PNG\r\n\x1a\n"


# --------------------------------------------------------------------------------------- config
def test_shipped_catalogue_is_the_rig_block_and_cites_its_source(cfg):
    cat = cfg["catalogue"]
    assert cat["block"].startswith("HIWIN HGH25CA")
    assert {n: c["normal_N_per_um"] for n, c in cat["classes"].items()} == {"Z0": 520.0, "ZA": 630.0, "ZB": 730.0}
    assert "Table 1.13" in cat["source"] and "verify against the current catalogue" in cat["source"]
    # the block the rig is built of: HGH25CA is 48 mm wide and 84 mm long on a 23 x 22 mm rail
    c, r = cfg["rig"]["carriages"], cfg["rig"]["rails"]
    assert (c["width_m"], c["length_m"], r["width_m"], r["height_m"]) == (0.048, 0.084, 0.023, 0.022)


def test_catalogue_is_optional(cfg):
    other = copy.deepcopy(cfg)
    del other["catalogue"]
    normalised, problems = check_config(other)
    assert problems == [] and normalised["catalogue"] == {"block": "", "source": "", "classes": {}}


@pytest.mark.parametrize("change, line", [
    (lambda c: c["catalogue"]["classes"]["ZA"].update(normal_N_per_um=6.3e8),
     "catalogue.classes.ZA.normal_N_per_um: 6.3e8 must be <= 100000 — give the radial (normal) rigidity of one "
     "block in N/um, not N/m (> 0 and <= 100000)"),
    (lambda c: c["catalogue"]["classes"]["ZA"].pop("normal_N_per_um"),
     "catalogue.classes.ZA.normal_N_per_um: missing — add it: the radial (normal) rigidity of one block in N/um, "
     "not N/m, > 0 and <= 100000"),
    (lambda c: c["catalogue"]["classes"]["ZB"].update(lateral_N_per_um=0.0),
     "catalogue.classes.ZB.lateral_N_per_um: 0 must be > 0 — give the lateral rigidity of one block in N/um, "
     "not N/m (> 0 and <= 100000)"),
    (lambda c: c["catalogue"]["classes"]["ZA"].update(radial_N_per_um=630.0),
     "catalogue.classes.ZA.radial_N_per_um: unknown key — did you mean 'normal_N_per_um'? "
     "(allowed: description, normal_N_per_um, lateral_N_per_um)"),
    (lambda c: c["catalogue"]["classes"].update(ZC=800.0),
     "catalogue.classes.ZC: 800 is a number, expected a mapping — write ZC as a mapping with keys description, "
     "normal_N_per_um, lateral_N_per_um"),
    (lambda c: c["catalogue"].update(source=""),
     "catalogue.source: '' is empty — give the catalogue source (publisher; document; year; page or table) as text"),
    (lambda c: c["catalogue"].pop("block"),
     "catalogue.block: '' is empty — give the name of the block the classes are of as text"),
], ids=["N_per_m_given", "normal_missing", "lateral_zero", "misspelt", "class_not_a_mapping", "no_source",
        "no_block"])
def test_malformed_catalogue_is_refused_with_where_what_and_how(cfg, change, line):
    bad = copy.deepcopy(cfg)
    change(bad)
    assert check_config(bad)[1] == ["config.yaml: " + line]

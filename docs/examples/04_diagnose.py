"""Which physical effect does the model lack?  A diagnosis on synthetic data with a hidden effect.

Run from the repository root:  python docs/examples/04_diagnose.py

The "test" is synthesised from a truth the diagnosis never sees (jointid.synthetic.generate): joint
stiffness, a library effect at a magnitude, noise.  `study.diagnose` calibrates the baseline, scores
every library effect against the residual, refits the leading ones and gives a verdict
(docs/effects.md).  With your own data, pass its folder or UFF file instead.
"""

import tempfile
import textwrap
from pathlib import Path

from jointid import Study

ROOT = Path(__file__).resolve().parents[2]
# The rig of the synthetic diagnosis tests: normal and lateral joint stiffness identified, the feed
# joint fixed (so that a feed effect is not absorbed by an identified parameter).
study = Study.from_config([ROOT / "config.yaml", ROOT / "tests" / "coarse_config.yaml"], overrides={
    "joints": {"parameters": {"k_feed_N_per_m3": None}, "fixed": {"k_feed_N_per_m3": 1.0e10}}})

HIDDEN = {"em_preload": {"beta": 0.15}}  # the motors' attraction stiffens the joints when powered
truth = {"joints": {"k_normal_N_per_m3": 8.0e11, "k_lateral_N_per_m3": 6.0e11},
         "states": {"power_off": {"em_force_N": 0.0}, "power_on": {"em_force_N": 1000.0}},
         "measurement": {"band_Hz": [100.0, 3500.0], "max_modes": 10, "shapes": True},
         "effects": HIDDEN, "noise": {"seed": 11, "frequency_pct": 0.2, "shape_pct": 2.0}}

with tempfile.TemporaryDirectory() as tmp:
    test = study.synthetic_dataset(truth, Path(tmp) / "test")
    print(f"synthetic test: {', '.join(f'{s} {len(test.freqs(s))} modes' for s in test.states)}, "
          f"hidden effect {list(HIDDEN)[0]}")
    found = study.diagnose(test)

print(f"diagnosis in {found.timing_s:.1f} s\n")
cols = ["effect", "explained_fraction", "explains", "estimate", "max_abs_error_pct_after"]
print(found.ranking[cols].head(4).round(3).to_string(index=False))
print("\nlargest error per rung of the ladder:")
print(found.ladder_summary().round(2).to_string(index=False))
print("\nverdict:", textwrap.shorten(found.verdict, 240))
print("best-ranked effect:", found.top_effect)

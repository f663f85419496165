"""Identify the joint stiffness from the paper's measured frequencies, state by state.

Run from the repository root:  python docs/examples/03_identify.py

`study.identify` is the workflow's FE polish: Gauss-Newton on the full FE model from a start (here
the default, the geometric mean of the bounds).  It is a local search.  The method (`snakemake -j2`,
or `study.run_method()`: example 05_tables.py) first searches the whole box on response surfaces from a
DOE and then polishes, and it also extrapolates over mesh refinement; use it for the published numbers
(docs/results.md).
"""

from pathlib import Path

from jointid import Study

ROOT = Path(__file__).resolve().parents[2]
study = Study.from_config([ROOT / "config.yaml", ROOT / "tests" / "coarse_config.yaml"])
paper = study.dataset(ROOT / "data" / "paper")  # frequencies only: paired by frequency at every iterate

found = {}
for state in paper.states:
    fit = study.identify(paper, state)
    found[state] = fit
    print(f"{state}: {fit.iterations} iterations, chi2 {fit.chi2:.1f} on {fit.dof} degrees of freedom, "
          f"max |error| {fit.max_abs_error_pct:.2f} %")
    print(fit.table().to_string(index=False, float_format="%.4g"))
    print(fit.modes_table().round(2).to_string(index=False))
    for m in fit.unpaired_visible:  # a model mode the test should have seen, counted as a misfit
        print(f"unpaired but visible: {m['freq_Hz']:.0f} Hz ({m['misfit_pct']:+.1f} % from {m['target_Hz']:.0f} Hz)")
    print()

# The identified stiffness is remembered per state: compare() and modes() of that state start from it.
after = study.compare(paper)
paired = after[after.status == "paired"]
print("model at the identified stiffness vs the test, max |error| per state:",
      ", ".join(f"{s} {g.error_pct.abs().max():.2f} %" for s, g in paired.groupby("state", sort=False)))

# What switching the motors on does to the joints (the electromagnetic attraction preloads them).
for name in found["power_off"].theta:
    off, on = found["power_off"].theta[name], found["power_on"].theta[name]
    print(f"{name}: power_off {off:.3g}, power_on {on:.3g} N/m^3 (ratio {on / off:.2f})")

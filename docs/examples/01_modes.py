"""Solve the rig's FE model and look at its modes.

Run from the repository root:  python docs/examples/01_modes.py

The coarse test mesh (tests/coarse_config.yaml over config.yaml) keeps it to a few seconds; drop the
second file for the default mesh.  Joint stiffness is per unit contact area and unit relative
displacement, in N/m^3; frequencies in Hz.
"""

from pathlib import Path

from jointid import Study

ROOT = Path(__file__).resolve().parents[2]
study = Study.from_config([ROOT / "config.yaml", ROOT / "tests" / "coarse_config.yaml"])

# 1. The joint parameters: the workflow identifies these; their default is the geometric mean of the bounds.
print(study.parameters().to_string(index=False))

# 2. The modes at the defaults.  `theta` sets any of them (N/m^3).
modes = study.modes(n=8)
model = study.model()
print(f"\nFE model: {model.n_dofs} DOFs, {len(modes.labels)} measured DOFs at {len(study.points())} points")
print(modes.table().round({"freq_Hz": 1, "strain_joints": 2}).to_string(index=False))

# 3. What the solve was given: K = K0 + sum c_t K_t and M = M0 + sum c_t M_t.
joints = {t: c for t, c in modes.k_coefficients.items() if t.startswith(("K_top", "K_flank"))}
print("\njoint-layer coefficients (N/m^3):", ", ".join(f"{t} {c:.3g}" for t, c in joints.items()))
print("mass coefficients:", ", ".join(f"{t} {c:.3g}" for t, c in modes.m_coefficients.items()))

# 4. The first mode's shape at the first table points (m/sqrt(kg), mass-normalised).
print("\nmode 1 at the table points:")
print(modes.shape(1).head(4).to_string(index=False, float_format="%.4f"))

# 5. A stiffer feed joint raises the feed mode and leaves the bounce modes nearly alone.
stiff = study.modes({"k_feed_N_per_m3": 4.0e10}, n=8)
print("\nk_feed 4.0e10 N/m^3 instead of the default:")
for j in range(4):
    print(f"  mode {j + 1} {modes.descriptions[j]:<14} {modes.freqs_Hz[j]:7.1f} -> {stiff.freqs_Hz[j]:7.1f} Hz")

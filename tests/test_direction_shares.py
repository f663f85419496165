"""Each joint direction's share of a mode's strain energy from an energy table (jointid.identification.direction_shares)."""
import numpy as np
import pandas as pd
import pytest

from jointid.errors import ModelError
from jointid.identification.direction_shares import direction_shares

TERMS = {"k_normal_N_per_m3": ["K_top_y"], "k_lateral_N_per_m3": ["K_flank_x"],
         "k_feed_N_per_m3": ["K_top_z", "K_flank_z"]}


def test_shares_sum_each_direction_s_layers_and_carriages():
    energy = pd.DataFrame({"kinetic_table": [0.9, 0.8], "strain_K_top_y@1": [0.1, 0.2], "strain_K_top_y@2": [0.05, 0.0],
                           "strain_K_top_z": [0.3, 0.01], "strain_K_flank_z": [0.2, 0.02], "strain_K_railfix": [0.1, 0.1],
                           "strain_joints": [0.65, 0.23]})
    out = direction_shares(energy, TERMS, list(TERMS))
    assert np.allclose(out, [[0.15, 0.0, 0.5], [0.2, 0.0, 0.03]])  # no K_flank_x column: no energy
    with pytest.raises(ModelError, match="k_tilt_N_per_m3: no joint-layer terms"):
        direction_shares(energy, TERMS, ["k_tilt_N_per_m3"])

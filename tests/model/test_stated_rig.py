"""The simulated rig states its mass and drive damping in its runs; the workbench then fixes them."""

from __future__ import annotations

from rigctl.config.loader import default_config
from rigctl.model import Drive, Simulator, build_model
from rigctl.records.rig_description import campaign_description
from rigctl.rigs import open_rig


def test_the_simulated_rig_states_its_mass_and_damping() -> None:
    model = build_model("paper", params={"m_kg": 0.02, "c0_N_s_per_m": 1.5})
    with open_rig("sim", default_config(), model=model) as rig:
        stated = rig.stated_parameters()
    assert stated == {"rig.m_kg": "0.02", "rig.c0_N_s_per_m": "1.5"}
    run = Simulator(model).run(Drive.constant(300.0, 1e-5, 2.0)).to_measured()
    assert {k: v for k, v in run.metadata.items() if k.startswith("rig.")} == stated
    assert campaign_description([run]).fixed == {"m_kg": 0.02, "c0_N_s_per_m": 1.5}

"""Child process of test_udp_multicast.py: a simulated DAQ node on a udp_multicast CAN bus.

Holds 123.456 N on the virtual rig and advances its clock for a few seconds so the node streams.
"""

from __future__ import annotations

import sys
import time

from sim_devices.can_daq_sim import CanDaqSim, CanDaqSimConfig
from sim_devices.sensors import ForceSensorSpec, ProbeSpec
from sim_devices.virtual_rig import VirtualRig, VirtualRigConfig


def main(channel: str) -> None:
    quiet = (ProbeSpec(noise_rms_m=0.0), ProbeSpec(noise_rms_m=0.0))
    rig = VirtualRig(config=VirtualRigConfig(probes=quiet))
    rig.normal.enable()
    rig.normal.move_to(rig.config.contact.z_for_fn_m(123.456), 2e-3)
    rig.advance_to(1.0)
    sensor = ForceSensorSpec(noise_rms_N=(0.0, 0.0, 0.0), analog_noise_rms_V=0.0)
    sim = CanDaqSim(rig, CanDaqSimConfig(interface="udp_multicast", channel=channel, sensor=sensor))
    sim.start()
    print("ready", flush=True)
    for _ in range(400):  # 4 s of rig time in 10 ms steps, about real time
        rig.advance_by(10 / 1024)
        time.sleep(0.01)
    sim.stop()


if __name__ == "__main__":
    main(sys.argv[1])

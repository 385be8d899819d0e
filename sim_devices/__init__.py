"""Simulated devices of the stick-slip rig: one virtual rig, its devices, over the real protocols.

See docs/simulated-rig.md. Entry point: :func:`sim_devices.backends.open_sim_rig`.
"""

"""The run service: protocol runs in their own process, so they outlive the operator's window.

``rigctl.runservice.server`` owns the rig and runs protocols; ``rigctl.runservice.client`` is what the
GUI uses to start it, connect, send commands and receive plan, progress, live data and outcome.
"""

"""The CAN DAQ across processes on python-can's udp_multicast bus (simulator in one process, the real
CanDaq driver in another).

Multicast must not leave this machine, so the test runs in a private network namespace
(`unshare -n`) whose only interface is its own loopback, with the multicast route pointed at it.
"""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
import textwrap
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
CHANNEL = "239.74.163.2"

DRIVER_SIDE = textwrap.dedent(
    f"""
    import subprocess, sys, time
    import numpy as np
    from drivers.can_daq import CanDaq, CanDaqConfig

    node = subprocess.Popen(
        [sys.executable, "tests/sim_devices/udp_multicast_node.py", "{CHANNEL}"],
        stdout=subprocess.PIPE, text=True,
    )
    assert node.stdout.readline().strip() == "ready"
    daq = CanDaq(CanDaqConfig(interface="udp_multicast", channel="{CHANNEL}"))
    daq.start()
    counters, fz = [], []
    deadline = time.monotonic() + 3.0
    while sum(map(len, counters)) < 1024 and time.monotonic() < deadline:
        block = daq.read_block(256, timeout_s=0.5)
        counters.append(block.counter)
        fz.append(block.fz_N)
    daq.stop()
    daq.close()
    node.wait(timeout=10)
    c = np.concatenate(counters)
    f = np.concatenate(fz)
    print("samples", c.size, "gaps", int(np.sum(np.diff(c) != 1)), "dropped", block.dropped_total)
    print("fz", float(f.min()), float(f.max()))
    """
)


def _namespace_available() -> bool:
    if shutil.which("unshare") is None or shutil.which("ip") is None:
        return False
    probe = subprocess.run(["unshare", "-n", "true"], capture_output=True)
    return probe.returncode == 0


@pytest.mark.skipif(not _namespace_available(), reason="needs `unshare -n` (root) to keep multicast local")
@pytest.mark.slow
def test_daq_streams_across_processes_on_udp_multicast() -> None:
    script = (
        "ip link set lo up && ip route add 239.0.0.0/8 dev lo && "
        f"{sys.executable} -c {subprocess.list2cmdline([DRIVER_SIDE])}"
    )
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    out = subprocess.run(
        ["unshare", "-n", "sh", "-c", script], cwd=ROOT, env=env, capture_output=True, text=True,
        timeout=60,
    )
    assert out.returncode == 0, out.stderr[-2000:]
    lines = dict(line.split(" ", 1) for line in out.stdout.strip().splitlines())
    samples, _, gaps, _, dropped = lines["samples"].split()
    assert int(samples) >= 1024
    assert int(gaps) == 0 and int(dropped) == 0
    fz_min, fz_max = map(float, lines["fz"].split())
    # 123.456 N is 4938 counts of 0.025 N: 123.45 N, within half a count
    assert fz_min == pytest.approx(123.45, abs=0.0125) and fz_max == pytest.approx(123.45, abs=0.0125)

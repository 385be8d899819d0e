"""From a suggestion to a run: an `indistinguishable` diagnosis names runnable protocols; running
them on the simulated rig and diagnosing again names the hidden effect.

The case: the rig's physics has interface damping (the simulated rig's `[sim] effects`); a short
TLRE campaign (three slips) is explained almost as well by rate-and-state friction, so the verdict
is `indistinguishable` with the protocols that reveal each. The suggested runs are run as an
operator would, `rigctl run PROTOCOL --param ...` on the simulated rig (through the same dry run,
limits and safe state), and their run files diagnosed with the same candidates.
"""

from __future__ import annotations

import json
import shlex
from pathlib import Path

import pytest

from rigctl.cli.main import main
from rigctl.model import build_model
from rigctl.workbench.campaigns import simulate_campaign, write_campaign

pytestmark = pytest.mark.slow  # full fits or diagnoses: the slow tier (make test-all)

HIDDEN = "interface_damping"
CANDIDATES = "interface_damping,rate_state"


def _diagnose_json(capsys: pytest.CaptureFixture[str], *data: str) -> dict:  # type: ignore[type-arg]
    capsys.readouterr()
    assert main(["model", "diagnose", *data, "--candidates", CANDIDATES, "--workers", "1",
                 "--json"]) == 0
    return json.loads(capsys.readouterr().out)


# end to end: two diagnoses and two protocol runs on the simulated rig, 150-180 s of CPU; a full
# suite run beside two benchmarks took it past the default 300 s limit (which is for hangs)
@pytest.mark.timeout(900)
@pytest.mark.xfail(strict=False, reason="the premise depends on the machine: with the same code "
                   "and seeds, the first campaign's diagnosis is 'indistinguishable' on one "
                   "machine (an AVX-512 Xeon, 2026-11-30: the test then passes end to end) and "
                   "names the hidden interface_damping directly on another (delta BIC -18 "
                   "against -11.8 for rate_state); near-ties of the ranking's fits follow "
                   "floating-point differences between machines. A case that needs the suggested "
                   "run on every machine is to be found (issue 34)")
def test_suggested_runs_tell_indistinguishable_effects_apart(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    runs = simulate_campaign(build_model("paper", effects=[HIDDEN]), "tlre", seed=3,
                             duration_scale=0.33)
    first = tmp_path / "first"
    write_campaign(runs, first)
    diag = _diagnose_json(capsys, str(first))
    assert diag["verdict"] == "indistinguishable", diag["ranking"]
    assert set(diag["candidates"]) == {"interface_damping", "rate_state"}
    suggested = diag["suggest_runs"]
    assert {s["reveals"] for s in suggested} == {"interface_damping", "rate_state"}
    config = tmp_path / "rig.toml"
    config.write_text(f'[sim]\neffects = ["{HIDDEN}"]\n')
    made = []
    for i, s in enumerate(suggested):
        argv = shlex.split(s["command"])
        assert argv[:3] == ["rigctl", "run", s["protocol"]]
        out = tmp_path / f"suggested_{i}.h5"
        rc = main([*argv[1:], "--config", str(config), "--speed", "max", "--no-camera",
                   "--out", str(out)])
        assert rc == 0, capsys.readouterr().err
        made.append(str(out))
    again = _diagnose_json(capsys, str(first), *made)
    assert again["verdict"] == HIDDEN, again["ranking"]

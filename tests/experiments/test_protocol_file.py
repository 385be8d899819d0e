"""Protocol files: loaded from the explicit path only, checked like the built-in protocols, with
one-line errors naming the file (and the line) when they cannot be used."""

from __future__ import annotations

import math
import sys
import textwrap
from pathlib import Path

import pytest

from experiments.errors import PlanError
from experiments.protocol_file import ProtocolFileError, load_protocol_file, looks_like_a_file
from experiments.runner import dry_run, get_protocol
from rigctl.config.loader import default_config
from rigctl.rigs import open_rig

EXAMPLE = Path(__file__).resolve().parents[2] / "docs" / "examples" / "load_steps.py"

HEADER = textwrap.dedent('''
    from dataclasses import dataclass

    from experiments.normal_load import LoadNormal, ReleaseNormal
    from experiments.protocols import Protocol, param
    from experiments.steps import Hold, MoveTangential, Step
''')

FIRST = HEADER.count("\n") + 1  # the first line of a body written after the header


def write(tmp_path: Path, body: str, name: str = "proto.py") -> Path:
    path = tmp_path / name
    path.write_text(HEADER + textwrap.dedent(body))
    return path


@pytest.fixture(scope="module")
def limits():
    with open_rig("sim", default_config(), speed=math.inf) as rig:
        yield rig.limits, rig.devices.tangential_stage.position_m()


def test_the_worked_example_loads_with_its_parameters_and_steps():
    loaded = load_protocol_file(EXAMPLE)
    p = loaded.protocol
    assert p.name == "load_steps"
    assert [d.name for d in p.params] == ["forces_N", "velocity_m_s", "slide_m", "settle_s",
                                          "preload_factor", "preload_hold_s"]
    forces = next(d for d in p.params if d.name == "forces_N")
    assert forces.unit == "N" and forces.is_list
    names = [s.describe() for s in p.steps({d.name: d.default for d in p.params})]
    assert names[0] == "load Fn to 200 N (pre-load 240 N)" and names[3] == "load Fn to 300 N"
    assert names[-2:] == ["release the normal load", "return the tangential stage to the start at 50 um/s"]
    assert loaded.path == EXAMPLE and len(loaded.sha256) == 64
    assert loaded.metadata() == {"protocol_file": str(EXAMPLE), "protocol_file_sha256": loaded.sha256}


def test_a_file_protocol_is_refused_by_the_dry_run_exactly_like_a_built_in_one(limits):
    lim, x0 = limits
    mine = load_protocol_file(EXAMPLE).protocol
    given = {"forces_N": "300", "slide_m": "0.25", "velocity_m_s": "1.3e-6"}
    with pytest.raises(PlanError) as from_file:
        dry_run(mine, given, lim, x0)
    with pytest.raises(PlanError) as built_in:
        dry_run(get_protocol("tlre"), {"travel_m": "0.25"}, lim, x0)
    assert "above the maximum 0.2 m" in str(from_file.value)
    assert str(from_file.value) == str(built_in.value)
    with pytest.raises(PlanError, match="peak normal force 1080 N exceeds the limit 800 N"):
        dry_run(mine, {"forces_N": "900,300"}, lim, x0)  # the first loading, with its pre-load
    with pytest.raises(PlanError, match="'load Fn to 900 N': peak normal force 900 N exceeds"):
        dry_run(mine, {"forces_N": "300,900"}, lim, x0)  # a later one
    with pytest.raises(PlanError, match="has no parameter 'fn_N'"):
        dry_run(mine, {"fn_N": "300"}, lim, x0)


def test_only_the_explicit_path_is_loaded_and_the_import_path_is_untouched(tmp_path, monkeypatch):
    write(tmp_path, '''
        @dataclass(frozen=True)
        class P:
            fn_N: float = param(100.0, "N", "force")

        PROTOCOL = Protocol("hold_once", "load, hold, release", P,
                            lambda p: [LoadNormal(p.fn_N), Hold(1.0), ReleaseNormal()])
    ''', name="hold_once.py")
    monkeypatch.chdir(tmp_path)
    search_path = list(sys.path)
    with pytest.raises(ProtocolFileError, match=r"nosuch\.py: no such file"):
        load_protocol_file("nosuch.py")
    assert load_protocol_file("hold_once.py").protocol.name == "hold_once"
    assert sys.path == search_path and "hold_once" not in sys.modules
    assert looks_like_a_file("hold_once.py") and looks_like_a_file("dir/x")
    assert not looks_like_a_file("tlre")


@pytest.mark.parametrize(("body", "message"), [
    ("x = 1\n", r"proto.py: defines no Protocol \(expected e.g. PROTOCOL = Protocol"),
    ("def f(:\n    pass\n", rf"proto.py, line {FIRST}: syntax error: "),
    ("\n\nvalue = 1 / 0\n", rf"proto.py, line {FIRST + 2}: ZeroDivisionError: division by zero"),
    ("PROTOCOL = 3\n", r"proto.py: PROTOCOL is a int, not a Protocol"),
    ('''
     @dataclass(frozen=True)
     class P:
         fn_N: float = 300.0

     PROTOCOL = Protocol("plain", "no param()", P, lambda p: [])
     ''', r"parameter 'fn_N' is not declared with param\(default, unit, doc\)"),
    ('''
     @dataclass(frozen=True)
     class P:
         fn_N: float = param(300.0, "N", "force")

     A = Protocol("a", "one", P, lambda p: [])
     B = Protocol("b", "two", P, lambda p: [])
     ''', r"defines 2 Protocols \(A, B\); name the one to run PROTOCOL"),
    ('''
     @dataclass(frozen=True)
     class P:
         fn_N: float = param(300.0, "N", "force")

     PROTOCOL = Protocol("tlre", "a second tlre", P, lambda p: [])
     ''', r"'tlre' is the name of a built-in protocol"),
])
def test_a_file_that_cannot_be_used_is_one_line_naming_it(tmp_path, body, message):
    path = write(tmp_path, body)
    with pytest.raises(ProtocolFileError, match=message) as err:
        load_protocol_file(path)
    assert "\n" not in str(err.value)


def test_steps_of_the_files_own_classes_are_refused_by_the_dry_run(tmp_path, limits):
    """A file's own Step subclass could skip the limit checks in its plan: not run."""
    path = write(tmp_path, '''
        class Teleport(Step):
            def plan(self, state, limits):
                return 0.0  # no check at all

        @dataclass(frozen=True)
        class P:
            distance_m: float = param(0.5, "m", "how far")

        PROTOCOL = Protocol("teleport", "moves without checks", P,
                            lambda p: [Teleport(), MoveTangential(p.distance_m, 1e-5)])
    ''')
    lim, x0 = limits
    with pytest.raises(PlanError, match="step 1 is a Teleport, not one of the library's steps"):
        dry_run(load_protocol_file(path).protocol, {}, lim, x0)

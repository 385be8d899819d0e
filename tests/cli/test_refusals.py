"""Values the rig cannot mean are refused in the dry run, with one line naming the value."""

from __future__ import annotations

import pytest

from rigctl.cli.main import main


@pytest.mark.parametrize(("argv", "words"), [
    (["run", "tlre", "--dry-run", "--param", "travel_m=-1e-4"], ("travel_m", "negative")),
    (["run", "tlre", "--dry-run", "--param", "velocity_m_s=0"], ("velocity_m_s", "above 0")),
    (["run", "force_sweep", "--dry-run", "--param", "forces_N=150,,250"], ("empty item",)),
    (["run", "tlre", "--dry-run", "--param", "velocity_m_s=1e-12"],
     ("810,000,102 s", "is a unit wrong")),
    (["run", "tlre", "--dry-run", "--speed", "0.5"], ("--speed 0.5", "use --speed max")),
    (["run", "tlre", "--dry-run", "--speed", "1e9"], ("--speed 1e9",)),
])
def test_a_value_the_rig_cannot_mean_is_refused(argv: list[str], words: tuple[str, ...],
                                                capsys: pytest.CaptureFixture[str]) -> None:
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and err.startswith("rigctl: error:"), err
    for w in words:
        assert w in err, err


def test_the_defaults_still_plan(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["run", "force_sweep", "--dry-run", "--param", "forces_N=150,250"]) == 0
    assert "dry run: nothing moved" in capsys.readouterr().out


def test_the_dry_run_states_the_file_size_and_refuses_a_disk_too_small(
        monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]) -> None:
    import shutil
    from collections import namedtuple

    assert main(["run", "slide_hold_slide", "--dry-run", "--no-camera"]) == 0
    out = capsys.readouterr().out
    assert "run file: about 19 MB (19 MB of samples)" in out
    usage = namedtuple("usage", "total used free")
    monkeypatch.setattr(shutil, "disk_usage", lambda _p: usage(10**9, 10**9 - 10**8, 10**8))
    assert main(["run", "slide_hold_slide", "--dry-run"]) == 2  # about 1.8 GB of frames
    err = capsys.readouterr().err
    assert "not enough" in err and "--no-camera" in err and err.count("\n") == 1


def test_a_camera_the_simulator_cannot_render_is_refused_in_one_line(
        tmp_path, capsys: pytest.CaptureFixture[str]) -> None:  # type: ignore[no-untyped-def]
    cfg = tmp_path / "cam.toml"
    cfg.write_text("[camera]\nwidth_px = 16384\nheight_px = 16384\n")
    assert main(["run", "tlre", "--dry-run", "--config", str(cfg)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "at most 640 x 480 px" in err


@pytest.mark.slow
def test_a_reader_that_goes_away_is_not_a_traceback() -> None:
    """`rigctl run tlre --dry-run | head -1`: the pipe closes before the output ends."""
    import subprocess
    import sys

    proc = subprocess.Popen([sys.executable, "-m", "rigctl.cli.main", "run", "tlre", "--dry-run"],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE)
    assert proc.stdout is not None and proc.stderr is not None
    proc.stdout.close()  # nobody reads: every write of the command meets a closed pipe
    err = proc.stderr.read().decode()
    assert proc.wait(timeout=120) == 0
    assert "Traceback" not in err and "BrokenPipe" not in err, err


def test_force_onto_a_device_is_refused_and_the_node_kept(
        tmp_path, capsys: pytest.CaptureFixture[str]) -> None:  # type: ignore[no-untyped-def]
    """`run --out <a character device> --force`: one line before any work; the node stays."""
    import os
    import stat

    node = tmp_path / "null"
    try:
        os.mknod(node, stat.S_IFCHR | 0o666, os.makedev(1, 3))  # a /dev/null of our own
    except PermissionError:
        pytest.skip("creating a device node needs CAP_MKNOD")
    argv = ["run", "tlre", "--speed", "max", "--no-camera", "--out", str(node), "--force"]
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "is a character device, not a regular file" in err, err
    assert stat.S_ISCHR(os.stat(node).st_mode)


def test_a_plan_past_the_step_limit_is_refused_at_once(capsys: pytest.CaptureFixture[str]) -> None:
    """`--param repetitions=1000000000 --dry-run` built its steps for minutes with memory growing;
    refused in one line naming the parameter and the limit before any step is built."""
    import time

    t0 = time.monotonic()
    assert main(["run", "tlre", "--dry-run", "--param", "repetitions=1000000000"]) == 2
    assert time.monotonic() - t0 < 10.0
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "repetitions" in err and "at most 10,000 steps" in err, err


def test_a_parameter_given_twice_is_refused(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["run", "tlre", "--dry-run", "--param", "fn_N=300", "--param", "fn_N=250"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "--param fn_N is given twice (300 and 250)" in err, err


@pytest.mark.parametrize(("argv", "expected"), [
    (["simulate", "--velocity", "-1e-5", "--duration", "0.5"], None),  # a value: runs
    (["simulate", "--fn", "-1e2", "--duration", "0.5"], "--fn -100 N is outside"),
    (["simulate", "--fn", "-inf"], "--fn: must be finite, got '-inf'"),
    (["simulate", "--segments", "-5:1e-5"], "duration must be positive, got -5 s"),
])
def test_a_negative_number_is_a_value_not_an_option(argv: list[str], expected: str | None,
                                                    capsys: pytest.CaptureFixture[str]) -> None:
    """`--velocity -1e-5` got argparse's "expected one argument" (its pattern knows no exponent)."""
    rc = main(argv)
    err = capsys.readouterr().err
    assert "expected one argument" not in err, err
    if expected is None:
        assert rc == 0, err
    else:
        assert rc == 2 and err.count("\n") == 1 and expected in err, err

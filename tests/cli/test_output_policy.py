"""One output-file policy for every command (docs/reliability.md, "Output files")."""

from __future__ import annotations

import contextlib
import subprocess
import sys
import time
from collections.abc import Iterator
from pathlib import Path

import pytest

RIGCTL = [sys.executable, "-m", "rigctl.cli.main"]


def _rigctl(*args: str, timeout: float = 120) -> subprocess.CompletedProcess[str]:
    return subprocess.run([*RIGCTL, *args], capture_output=True, text=True, timeout=timeout)


@contextlib.contextmanager
def _held_open(path: Path, mode: str) -> Iterator[subprocess.Popen[str]]:
    """Another process holding ``path`` open in ``mode`` for the block (as a recording would)."""
    holder = subprocess.Popen([sys.executable, "-c",
                               "import sys, time\nf = open(sys.argv[1], sys.argv[2])\n"
                               "print('open', flush=True)\ntime.sleep(60)\n", str(path), mode],
                              stdout=subprocess.PIPE, text=True)
    try:
        assert holder.stdout is not None and holder.stdout.readline().strip() == "open"
        yield holder
    finally:
        holder.kill()
        holder.wait()


def _one_line_error(proc: subprocess.CompletedProcess[str], *words: str) -> None:
    assert proc.returncode == 2, proc.stderr
    lines = proc.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("rigctl: error:"), proc.stderr
    for w in words:
        assert w in lines[0], lines[0]


@pytest.mark.slow
def test_an_existing_output_is_kept_unless_forced(tmp_path: Path) -> None:
    out = tmp_path / "a.csv"
    out.write_text("precious")
    _one_line_error(_rigctl("simulate", "--duration", "1", "--out", str(out)), "already exists",
                    "--force")
    assert out.read_text() == "precious"
    plot = tmp_path / "p.png"
    plot.write_text("precious")
    _one_line_error(_rigctl("simulate", "--duration", "1", "--plot", str(plot)), "--plot")
    assert plot.read_text() == "precious"
    proc = _rigctl("simulate", "--duration", "1", "--out", str(out), "--force")
    assert proc.returncode == 0, proc.stderr
    assert out.read_text().startswith("# ") or "t_s" in out.read_text()


@pytest.mark.slow
def test_export_refuses_an_existing_csv(tmp_path: Path) -> None:
    run = tmp_path / "r.h5"
    assert _rigctl("simulate", "--duration", "1", "--out", str(run)).returncode == 0
    csv = tmp_path / "r.csv"
    csv.write_text("precious")
    _one_line_error(_rigctl("export", str(run), "--csv", str(csv)), "already exists")
    assert csv.read_text() == "precious"
    assert _rigctl("export", str(run), "--csv", str(csv), "--force").returncode == 0


@pytest.mark.slow
def test_a_missing_folder_is_refused_not_created(tmp_path: Path) -> None:
    out = tmp_path / "no" / "such" / "a.csv"
    _one_line_error(_rigctl("simulate", "--duration", "1", "--out", str(out)), "does not exist")
    assert not (tmp_path / "no").exists()


@pytest.mark.slow
def test_a_report_path_is_checked_before_the_fit(tmp_path: Path) -> None:
    data = tmp_path / "d.csv"
    assert _rigctl("simulate", "--duration", "5", "--out", str(data)).returncode == 0
    not_a_folder = tmp_path / "report.html"
    not_a_folder.write_text("x")
    t0 = time.monotonic()
    _one_line_error(_rigctl("model", "compare", str(data), "--report", str(not_a_folder)),
                    "not a folder")
    assert time.monotonic() - t0 < 30.0  # refused at once, not after identifying the model


@pytest.mark.slow
def test_a_file_being_written_is_never_replaced(tmp_path: Path) -> None:
    target = tmp_path / "live.csv"
    target.write_text("being recorded\n")
    with _held_open(target, "a") as holder:
        _one_line_error(_rigctl("simulate", "--duration", "1", "--out", str(target), "--force"),
                        "being written by process", str(holder.pid))
        assert target.read_text() == "being recorded\n"


@pytest.mark.parametrize(("args", "words"), [
    (["--duration", "1e9"], ("samples", "shorten --duration")),
    (["--rate", "1e7"], ("--rate",)),
    (["--duration", "1", "--param", "mu_k=0.2"], ("mu_k", "not below mu_s")),
    (["--duration", "1", "--param", "mu_k=0.09", "--param", "mu_k=0.08"], ("given twice",)),
    # the stable stage may slip, but the initial stage's static peak is below the kinetic level
    (["--duration", "1", "--param", "mu_s=0.3", "--param", "mu_k=0.24"],
     ("cannot stick-slip", "mu_k (0.24) reaches mu_smax (0.2)")),
])
@pytest.mark.slow
def test_simulate_refuses_what_the_model_cannot_mean(tmp_path: Path, args: list[str],
                                                     words: tuple[str, ...]) -> None:
    _one_line_error(_rigctl("simulate", *args, "--out", str(tmp_path / "x.csv")), *words)
    assert not (tmp_path / "x.csv").exists()


@pytest.mark.slow
def test_an_implausible_velocity_is_warned_about(tmp_path: Path) -> None:
    proc = _rigctl("simulate", "--duration", "0.2", "--velocity", "0.5")
    assert proc.returncode == 0, proc.stderr
    assert "is the unit right" in proc.stderr


@pytest.mark.slow
def test_version_and_bare_command() -> None:
    proc = _rigctl("--version")
    assert proc.returncode == 0 and proc.stdout.startswith("rigctl 0."), proc.stdout
    proc = _rigctl()
    assert proc.returncode == 2
    assert "simulate" in proc.stdout and "Traceback" not in proc.stderr


def test_run_preflight_never_replaces_a_file_being_recorded(tmp_path: Path) -> None:
    """`rigctl run --force` and `import --force` go through the storage preflight."""
    from rigctl.errors import StorageError
    from rigctl.storage.preflight import check_output_path

    target = tmp_path / "live.h5"
    target.write_bytes(b"\x89HDF\r\n\x1a\n")
    with _held_open(target, "r+b"), pytest.raises(StorageError, match="being written by process"):
        check_output_path(target, overwrite=True)
    check_output_path(target, overwrite=True)  # released: --force may replace it


@pytest.mark.slow
def test_the_configured_storage_folder_is_made_but_never_a_tree(tmp_path: Path) -> None:
    """`rigctl run` without --out writes into storage.directory: that folder is created if its
    parent exists; a path whose parents are missing (a typo) is refused, nothing created."""
    bad = tmp_path / "rig_bad.toml"
    bad.write_text(f'[storage]\ndirectory = "{tmp_path}/no/such/runs"\n')
    _one_line_error(_rigctl("run", "tlre", "--config", str(bad), "--speed", "max",
                            "--no-camera"), "does not exist")
    assert not (tmp_path / "no").exists()


@pytest.mark.slow
def test_a_run_file_missing_a_listed_channel_is_one_line(tmp_path: Path) -> None:
    import h5py

    run = tmp_path / "r.h5"
    assert _rigctl("simulate", "--duration", "1", "--out", str(run)).returncode == 0
    with h5py.File(run, "r+") as f:
        del f["entry/daq/ft_N"]
    for cmd in (["info", str(run)], ["model", "compare", str(run)]):
        _one_line_error(_rigctl(*cmd), "lists channel(s) ft_N but has no")


def _deny_writes_in(folder: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """Emulate a read-only ``folder`` at the permission check (as root every folder is writable;
    the real-permission twin below runs where the tests do not run as root)."""
    import os

    from rigctl.io import outputs

    real_access = os.access

    def access(path: object, mode: int) -> bool:
        if Path(str(path)).resolve() == folder.resolve() and mode & os.W_OK:
            return False
        return real_access(path, mode)  # type: ignore[arg-type]

    monkeypatch.setattr(outputs.os, "access", access)


@pytest.mark.slow
def test_outputs_into_a_read_only_folder_are_refused_before_the_work(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    from rigctl.cli.main import main

    data = tmp_path / "d.csv"
    assert _rigctl("simulate", "--duration", "5", "--out", str(data)).returncode == 0
    run = tmp_path / "d.h5"
    assert _rigctl("simulate", "--duration", "5", "--out", str(run)).returncode == 0
    locked = tmp_path / "locked"
    locked.mkdir()
    _deny_writes_in(locked, monkeypatch)
    cases = [
        (["simulate", "--duration", "1", "--plot", str(locked / "p.png")], "--plot"),
        (["simulate", "--duration", "1", "--out", str(locked / "s.csv")], "--out"),
        (["model", "compare", str(data), "--report", str(locked / "rep")], "--report"),
        (["model", "diagnose", str(data), "--report", str(locked / "diag")], "--report"),
        (["export", str(run), "--csv", str(locked / "e.csv")], "--csv"),
        (["import", str(data), "--out", str(locked / "i.h5")], "--out"),
        (["analyse", str(data), "--out", str(locked / "an")], "--out"),
    ]
    for argv, option in cases:
        t0 = time.monotonic()
        assert main(argv) == 2, argv
        err = capsys.readouterr().err.strip().splitlines()
        assert len(err) == 1 and option in err[0] and "not writable" in err[0], err
        assert time.monotonic() - t0 < 20.0, argv  # refused before any fit or simulation
    assert list(locked.iterdir()) == []


@pytest.mark.skipif(sys.platform == "win32" or __import__("os").geteuid() == 0,
                    reason="root may write into any folder")
def test_a_really_read_only_folder_is_refused(tmp_path: Path) -> None:
    locked = tmp_path / "locked"
    locked.mkdir()
    locked.chmod(0o500)
    try:
        _one_line_error(_rigctl("simulate", "--duration", "1", "--plot", str(locked / "p.png")),
                        "not writable")
        assert list(locked.iterdir()) == []
    finally:
        locked.chmod(0o700)

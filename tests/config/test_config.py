"""The rig configuration: defaults, TOML round trip, errors that name the key, docs in sync."""

from __future__ import annotations

import dataclasses
import re
from pathlib import Path

import pytest

from drivers.modbus_stage import StageConfig
from rigctl.config import (
    ENV_VAR,
    ConfigError,
    default_config,
    load_config,
    load_effective_config,
    parse_config,
    to_toml,
)
from rigctl.config.adapters import force_limit_N, stage_config
from rigctl.config.reference import markdown_reference, reference_rows

DOCS = Path(__file__).resolve().parents[2] / "docs" / "configuration.md"


def test_defaults_are_the_simulated_rig_with_the_papers_numbers() -> None:
    c = default_config()
    assert c.rig.backend == "sim"
    assert c.daq.sample_rate_hz == 1024
    assert c.normal_stage.limits.max_force_N == 800.0
    assert c.normal_stage.limits.max_position_m == 0.025
    assert c.tangential_stage.limits.max_position_m == 0.200
    assert c.tangential_stage.counts_per_m == 3_125_000.0
    assert c.camera.frame_rate_hz == 60.0
    assert c.probes.d1.range_m == 74e-6
    assert c.storage.flush_interval_s <= 0.5


def test_toml_round_trip_is_exact() -> None:
    c = default_config()
    assert parse_config(to_toml(c)) == c
    changed = parse_config('[sim]\neffects = ["rate_state", "wear"]\n[daq]\nnode_id = 5\n')
    assert parse_config(to_toml(changed)) == changed


def test_a_file_only_needs_the_keys_it_changes(tmp_path: Path) -> None:
    path = tmp_path / "rig.toml"
    path.write_text(
        '[rig]\nbackend = "sim-wire"\noperator = "Han"\n'
        "[normal_stage.limits]\nmax_force_N = 500\n"  # an integer is a fine number
        '[channels]\nfn_sign = -1\n[probes.d2]\nurl = "loop://"\n'
    )
    c = load_config(path)
    assert c.rig.backend == "sim-wire" and c.rig.operator == "Han"
    assert c.normal_stage.limits.max_force_N == 500.0
    assert isinstance(c.normal_stage.limits.max_force_N, float)
    assert c.channels.fn_sign == -1 and c.probes.d2.url == "loop://"
    assert c.normal_stage.limits.max_position_m == 0.025  # untouched keys keep defaults
    with pytest.raises(dataclasses.FrozenInstanceError):
        c.rig.backend = "real"  # type: ignore[misc]


ERRORS = [
    (
        '[normal_stage.limits]\nmax_force_N = "abc"',
        'normal_stage.limits.max_force_N: expected a number, got "abc"',
    ),
    (
        "[normal_stage.limits]\nmax_force = 300",
        'normal_stage.limits.max_force: unknown key (did you mean "max_force_N"?)',
    ),
    ("[normal_stag]\nport = 1", 'normal_stag: unknown key (did you mean "normal_stage"?)'),
    (
        '[rig]\nbackend = "simm"',
        'rig.backend: expected one of "sim", "sim-wire", "real", got "simm" (did you mean "sim"?)',
    ),
    ("[normal_stage.limits]\nmax_force_N = 900", "normal_stage.limits.max_force_N: must be <= 800"),
    (
        "[tangential_stage.limits]\nmax_position_m = 0.3",
        "tangential_stage.limits.max_position_m: must be <= 0.2",
    ),
    ("[daq]\nsample_rate_hz = 1024.5", "daq.sample_rate_hz: expected a whole number, got 1024.5"),
    ("[daq]\nnode_id = true", "daq.node_id: expected a whole number, got true"),
    ("[daq]\ncommand_timeout_s = nan", "daq.command_timeout_s: expected a finite number, got nan"),
    ("[daq]\ncommand_timeout_s = -1", "daq.command_timeout_s: must be > 0, got -1"),
    ("[normal_stage]\nlimits = 3", "normal_stage.limits: expected a table, got 3"),
    ("[sim]\neffects = [1]", "sim.effects: expected an array of strings"),
    ("[channels]\nft_sign = 2", "channels: ChannelMap.ft_sign must be +1 or -1, got 2"),
    ('[channels]\nfn_axis = "fx"', "channels: ChannelMap: Ft and Fn cannot both be fx"),
    ('[channels]\nft_axis = "fq"', 'channels.ft_axis: expected one of "fx", "fy", "fz", got "fq"'),
    ("[channels]\nd2_channel = 0", "channels.d2_channel: D1 and D2 cannot both be analog input 0"),
    ("[channels]\nd1_channel = 5", "channels.d1_channel: must be <= 2, got 5"),
    (
        "[normal_stage.limits]\nmin_position_m = 0.02\nmax_position_m = 0.01",
        "normal_stage.limits.max_position_m: must be above min_position_m",
    ),
    ("[tangential_stage]\ncounts_per_m = 1e12", "tangential_stage.counts_per_m: 1e+12 counts/m"),
    (
        "[tangential_stage.limits]\nmax_velocity_m_s = 0.19\n[tangential_stage]\n"
        "velocity_counts_per_m_s = 1e11",
        "tangential_stage.limits.max_velocity_m_s",
    ),
    (
        "[tangential_stage.registers]\nvelocity = 3",
        "tangential_stage.registers: RegisterMap.velocity overlaps target_position",
    ),
    ('[normal_stage]\ntransport = "rtu"', 'normal_stage.serial_port: transport "rtu" needs'),
    ('[rig]\nbackend = "real"', 'tangential_stage.port: a "real" rig needs the Modbus TCP port'),
    (
        '[sim]\neffects = ["rate-state"]',
        'sim.effects: unknown effect "rate-state" (did you mean "rate_state"?)',
    ),
    ("x = ", "invalid TOML"),
]


@pytest.mark.parametrize(("text", "message"), ERRORS)
def test_errors_name_the_file_and_the_key(text: str, message: str) -> None:
    with pytest.raises(ConfigError) as info:
        parse_config(text, source="rig.toml")
    assert str(info.value).startswith(f"rig.toml: {message}"), str(info.value)
    assert "\n" not in str(info.value)


def test_a_real_rig_needs_every_address() -> None:
    text = '[rig]\nbackend = "real"\n[tangential_stage]\nport = 502\n[normal_stage]\nport = 503\n'
    with pytest.raises(ConfigError, match=r"probes\.d1\.url"):
        parse_config(text)
    text += '[probes.d1]\nurl = "/dev/ttyUSB0"\n[probes.d2]\nurl = "/dev/ttyUSB1"\n'
    with pytest.raises(ConfigError, match=r"camera\.source"):
        parse_config(text)
    c = parse_config(text + '[camera]\nsource = "0"\n')
    assert c.rig.backend == "real"


def test_missing_file_and_environment_variable(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    with pytest.raises(ConfigError, match="no such configuration file"):
        load_config(tmp_path / "absent.toml")
    monkeypatch.delenv(ENV_VAR, raising=False)
    assert load_effective_config(None) == (default_config(), None)
    path = tmp_path / "rig.toml"
    path.write_text('[rig]\noperator = "from env"\n')
    monkeypatch.setenv(ENV_VAR, str(path))
    config, source = load_effective_config(None)
    assert (config.rig.operator, source) == ("from env", path)
    other = tmp_path / "other.toml"
    other.write_text('[rig]\noperator = "explicit"\n')
    assert load_effective_config(other)[0].rig.operator == "explicit"  # --config wins


def test_drivers_get_their_own_config_objects() -> None:
    c = parse_config(
        '[normal_stage]\nword_order = "low_first"\nport = 1502\n'
        "[normal_stage.limits]\nmax_velocity_m_s = 1e-4\n"
    )
    sc = stage_config(c, "normal_stage")
    assert isinstance(sc, StageConfig)
    assert (sc.name, sc.word_order, sc.port, sc.counts_per_m) == ("normal", "low_first", 1502, 1_666_667.0)
    assert sc.limits.max_velocity_m_s == 1e-4 and sc.limits.max_position_m == 0.025
    assert sc.registers == c.normal_stage.registers
    assert force_limit_N(c) == 800.0


def test_docs_reference_is_current_and_complete() -> None:
    text = DOCS.read_text(encoding="utf-8")
    assert markdown_reference() in text, (
        "docs/configuration.md is stale: paste `python -m rigctl.config.reference` into it"
    )
    keys = [row[0] for row in reference_rows()]
    assert len(keys) == len(set(keys)) > 80
    documented = set(re.findall(r"^\| `([A-Za-z0-9_.]+)` \|", text, flags=re.MULTILINE))
    assert documented == set(keys)
    for key, _default, _unit, meaning in reference_rows():
        assert meaning, f"{key} has no description"


def test_adapters_build_every_device_config() -> None:
    from drivers.can_daq import CanDaqConfig
    from drivers.opencv_camera import CameraConfig
    from drivers.serial_probe import ProbeConfig
    from rigctl.config.adapters import (
        camera_config,
        daq_config,
        probe_config,
        virtual_rig_config,
    )

    c = parse_config(
        "[daq]\nsample_rate_hz = 2048\nbitrate = 0\n[channels]\nfn_sign = -1\n"
        '[probes.d2]\nurl = "socket://127.0.0.1:7000"\nrange_m = 5e-5\n'
        '[camera]\nsource = "2"\n[sim]\nseed = 7\n'
    )
    daq = daq_config(c)
    assert isinstance(daq, CanDaqConfig)
    assert (daq.rate_hz, daq.bitrate, daq.channel_map.fn_sign) == (2048.0, None, -1)
    with pytest.raises(ConfigError, match=r"probes\.d1\.url: no serial port"):
        probe_config(c, "d1")
    assert probe_config(c, "d1", url="/dev/pts/5").url == "/dev/pts/5"
    d2 = probe_config(c, "d2")
    assert isinstance(d2, ProbeConfig) and (d2.name, d2.url) == ("d2", "socket://127.0.0.1:7000")
    camera = camera_config(c)
    assert isinstance(camera, CameraConfig) and camera.source == 2
    with pytest.raises(ConfigError, match=r"camera\.source"):
        camera_config(default_config())
    from rigctl.config.adapters import camera_layout, daq_layout

    assert daq_layout(c).sample_rate_hz == 2048.0
    layout = camera_layout(c)
    assert (layout.height_px, layout.width_px, layout.compression) == (480, 640, "gzip")
    rig = virtual_rig_config(c)
    assert (rig.sample_rate_hz, rig.seed) == (2048.0, 7)
    assert rig.probes[1].range_m == 5e-5 and rig.probes[0].range_m == 74e-6


def test_a_byte_order_mark_is_named(tmp_path: Path) -> None:
    """A UTF-8 BOM (some Windows editors) got tomllib's "Invalid statement (at line 1, column 1)";
    UTF-16 got a codec error. Both are named, with what to do."""
    bom = tmp_path / "bom.toml"
    bom.write_bytes(b"\xef\xbb\xbf" + b'[rig]\noperator = "Han"\n')
    with pytest.raises(ConfigError, match=r"bom\.toml: starts with a UTF-8 byte-order mark .* "
                                          r"save the file as UTF-8 without BOM"):
        load_config(bom)
    utf16 = tmp_path / "utf16.toml"
    utf16.write_text('[rig]\noperator = "Han"\n', encoding="utf-16")
    with pytest.raises(ConfigError, match=r"utf16\.toml: is UTF-16 text; TOML is UTF-8"):
        load_config(utf16)
    latin1 = tmp_path / "latin1.toml"
    latin1.write_bytes('[rig]\noperator = "Jürgen"\n'.encode("latin-1"))
    with pytest.raises(ConfigError, match=r"latin1\.toml: cannot read: not UTF-8 text"):
        load_config(latin1)
    plain = tmp_path / "plain.toml"
    plain.write_text('[rig]\noperator = "Jürgen"\n', encoding="utf-8")
    assert load_config(plain).rig.operator == "Jürgen"

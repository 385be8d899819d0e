"""The rig configuration: typed sections, TOML in and out, defaults for the simulated rig.

See docs/configuration.md for every key, its default and unit.
"""

from rigctl.config.errors import ConfigError
from rigctl.config.loader import (
    ENV_VAR,
    default_config,
    from_dict,
    load_config,
    load_effective_config,
    parse_config,
    resolve_config_path,
    to_dict,
    to_toml,
)
from rigctl.config.schema import (
    ChannelMap,
    DaqSection,
    NormalStage,
    RigConfig,
    TangentialStage,
)

__all__ = [
    "ENV_VAR",
    "ChannelMap",
    "ConfigError",
    "DaqSection",
    "NormalStage",
    "RigConfig",
    "TangentialStage",
    "default_config",
    "from_dict",
    "load_config",
    "load_effective_config",
    "parse_config",
    "resolve_config_path",
    "to_dict",
    "to_toml",
]

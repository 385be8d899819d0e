"""``rigctl config show``: print the effective rig configuration as TOML.

The configuration comes from ``--config FILE``, else ``$RIGCTL_CONFIG``, else the built-in defaults
(the simulated rig). The output is a complete, valid configuration file: every key, defaults
included, so it is also the way to start a new one (``rigctl config show > rig.toml``).
"""

from __future__ import annotations

import argparse
import sys

ENV_VAR = "RIGCTL_CONFIG"  # rigctl.config.ENV_VAR; the config package is imported only when run


def register(subparsers: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    parser = subparsers.add_parser(
        "config", help="show the rig configuration", description=__doc__.split("\n\n")[0]
    )
    actions = parser.add_subparsers(dest="config_action", metavar="ACTION")
    actions.required = True
    show = actions.add_parser(
        "show",
        help="print the effective configuration as TOML",
        description=f"Print the effective configuration (from --config, else ${ENV_VAR}, else "
        "the built-in simulated rig) as a complete TOML file.",
    )
    show.add_argument("--config", metavar="FILE", default=None, help="rig configuration (TOML)")
    show.set_defaults(func=run_show)


def run_show(args: argparse.Namespace) -> int:
    from rigctl.config import load_effective_config, to_toml

    config, source = load_effective_config(args.config)
    origin = "built-in defaults (simulated rig)" if source is None else str(source)
    sys.stdout.write(f"# rigctl rig configuration; source: {origin}\n\n{to_toml(config)}")
    return 0

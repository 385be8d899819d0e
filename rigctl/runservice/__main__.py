"""``python -m rigctl.runservice``: see :mod:`rigctl.runservice.server`."""

import sys

from rigctl.runservice.server import main

sys.exit(main())

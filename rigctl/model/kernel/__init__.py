"""The compiled event-driven integrator of the stick-slip model (docs/model.md, section 3).

State: specimen position X and velocity V, the sensor filter output, the rate-and-state variable
theta, and for each Jenkins element either *stuck* (force f_i = g_i + kt X, offset g_i stored) or
*presliding* (force held at its static threshold +-c_i Fn_eff, paper Sec. 5.2: the back end slips
first in the initial stage). When no element is stuck the interface slides as a whole (*global slip*)
at the kinetic friction until the specimen velocity returns to zero, when every element sticks again.

Everything is compiled with numba and works on small typed arrays whose slots, rows and columns are
named in :mod:`rigctl.model.layout`. One module per concern:

* :mod:`~rigctl.model.kernel.loop` - :func:`advance`, the main loop over knots and output samples;
* :mod:`~rigctl.model.kernel.fast_stick` - the exact sample-to-sample recurrence of long stick phases;
* :mod:`~rigctl.model.kernel.linear_step` - the exact step between events (:mod:`rigctl.model.modal`)
  and how an event changes the elements;
* :mod:`~rigctl.model.kernel.event_search` - envelope test, grid scan at <= 1/16 of the ringing
  period and bisection to round-off;
* :mod:`~rigctl.model.kernel.global_slip` - start and end of a global slip, its event-table row;
* :mod:`~rigctl.model.kernel.nonlinear_slip` - the global slip with velocity/state-dependent friction
  (``stribeck``, ``rate_state``) by classical RK4 at 1/64 of the drive period, with the Stribeck cap;
* :mod:`~rigctl.model.kernel.free_step` - the specimens apart (Fn below contact);
* :mod:`~rigctl.model.kernel.output` - one output sample;
* :mod:`~rigctl.model.kernel.inputs`, :mod:`~rigctl.model.kernel.forces` - piecewise-linear inputs,
  drive force and element thresholds.

Developers: numba's on-disk cache (``NUMBA_CACHE_DIR``) keys each function by its own file (numba
0.68, pinned: a hash of the file's text; older numba: its time stamp), not by the files it calls.
After editing a module here, delete the cache folder or also change the text of the modules that
call it, up to ``loop.py`` (touching them no longer suffices); otherwise ``advance`` keeps the old
code.
"""

from __future__ import annotations

from rigctl.model.kernel.loop import advance
from rigctl.model.kernel.output import state_sample

__all__ = ["advance", "state_sample"]

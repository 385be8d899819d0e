"""Benchmark: a model with a plug-in term against the same term built in, side by side.

The same drag -c V (c = 30 N s/m) on the paper model, 3 s at 1e-4 m/s and 300 N (1024 Hz):

* ``built_in_general``: the library's ``interface_damping`` on the general path (forced there by a
  plug-in force that adds nothing), i.e. the term compiled into the integrator;
* ``plugin``: the drag as a plug-in force term (a first-class function call per evaluation);
* ``built_in_exact``: the library's ``interface_damping`` on the exact path (no plug-in term).

Target (issue 37): plugin / built_in_general >= 0.5 in speed. CPU seconds, medians of repeats.

``measure_linear_moves`` (always run): the two library effects stated as linear terms
(``interface_damping``: a drag -c V, ``normal_coupling``: Fn_eff = Fn + kappa K0 (x_stage - X);
``Effect.linear_terms``, on the exact path) against the same coefficient written straight into the
kernel's vector (``built_in``: what their ``apply`` hooks did before they moved), side by side on
the same runs: CPU seconds, ``<effect>_api_speed_vs_built_in`` (target >= 0.5) and the largest
|Ft| and |Fn| differences (0: the same bits). Both on the slide above and on the slide-hold-slide
below; the drag also as a plug-in force term on the general path, for the ratio a function term
would give, and a user's parallel spring -k_p (X - X(0)) as a linear term against the same spring
as a force term (``spring_linear_speed_vs_force_term``, max |dFt| between them).

``--library`` adds what moving a library effect onto the function terms would cost today:
``rate_state`` and ``presliding`` on their own paths (exact stick, RK4 only in ``rate_state``'s
slips) against the general path (forced there as above), on a slide-hold-slide of the workbench's
kind (2e-5 m/s, holds of 1 and 3 s, 300 N), and how far each library effect on the general path
(forced there as above) lies from its own exact path: the largest |Ft| difference and slip start
time difference, 3 s at 1e-4 m/s and 300 N (``<effect>_general_vs_exact_max_ft_N``, ``..._max_slip_start_s``).
"""

from __future__ import annotations

import json
import statistics
import sys
import time
from collections.abc import Callable, Mapping
from typing import Any

import numpy as np

from rigctl.model import Drive, Effect, LinearTerms, ParamSpec, Simulator, build_model, layout
from rigctl.model.effects import LIBRARY

C_N_S_PER_M = 30.0


def _drag(p: np.ndarray, x: float, v: float, t: float, fn: float, z: np.ndarray) -> float:
    return -p[0] * v


def _nothing(p: np.ndarray, x: float, v: float, t: float, fn: float, z: np.ndarray) -> float:
    return 0.0 * p[0]


class PluginDrag(Effect):
    name = "bench_drag"
    summary = "a drag -c V as a plug-in force"
    signature = "as interface_damping"
    reveal_protocol = "any"
    params = (ParamSpec("c_N_s_per_m", C_N_S_PER_M, 0.0, 300.0, "N s/m", "drag", off=0.0),)

    @staticmethod
    def force_term() -> Callable[..., Any]:
        return _drag


def _spring(p: np.ndarray, x: float, v: float, t: float, fn: float, z: np.ndarray) -> float:
    return -p[0] * x  # the benchmark's drives start at X(0) = 0


SPRING_PARAMS = (ParamSpec("k_N_per_m", 2e5, 0.0, 1e7, "N/m", "parallel spring", off=0.0),)


class ForceTermSpring(Effect):
    name = "bench_spring_force_term"
    summary = "a parallel spring -k_p X as a plug-in force term (general path)"
    signature = "peaks grow with the distance slid"
    reveal_protocol = "any"
    params = SPRING_PARAMS

    @staticmethod
    def force_term() -> Callable[..., Any]:
        return _spring


class LinearSpring(Effect):
    name = "bench_spring_linear"
    summary = "the same spring as a linear term (exact path)"
    signature = "peaks grow with the distance slid"
    reveal_protocol = "any"
    params = SPRING_PARAMS

    def linear_terms(self, values: Mapping[str, float]) -> LinearTerms:
        return LinearTerms(stiffness_N_per_m=values["k_N_per_m"])


class NoForce(Effect):
    name = "bench_nothing"
    summary = "a plug-in force of zero (puts a model on the general path)"
    signature = "none"
    reveal_protocol = "any"
    params = (ParamSpec("on", 1.0, 0.0, 1.0, "-", "active", off=0.0),)

    @staticmethod
    def force_term() -> Callable[..., Any]:
        return _nothing


def _cpu_s(sim: Simulator, drive: Drive, repeats: int) -> float:
    sim.run(drive)  # compile / load the cache
    times = []
    for _ in range(repeats):
        c0 = time.process_time()
        sim.run(drive)
        times.append(time.process_time() - c0)
    return statistics.median(times)


def measure(duration_s: float = 3.0, repeats: int = 3) -> dict[str, float]:
    drive = Drive.constant(300.0, 1e-4, duration_s)
    damp = {"interface_damping": {"c_N_s_per_m": C_N_S_PER_M}}
    models = {
        "built_in_general": build_model("paper", effects=["interface_damping", NoForce],
                                        effect_params=damp),
        "plugin": build_model("paper", effects=[PluginDrag]),
        "built_in_exact": build_model("paper", effects=["interface_damping"], effect_params=damp),
    }
    out = {f"{k}_cpu_s": _cpu_s(Simulator(m), drive, repeats) for k, m in models.items()}
    out["simulated_s"] = duration_s
    out["plugin_speed_vs_built_in_general"] = out["built_in_general_cpu_s"] / out["plugin_cpu_s"]
    out["plugin_speed_vs_built_in_exact"] = out["built_in_exact_cpu_s"] / out["plugin_cpu_s"]
    a = Simulator(models["plugin"]).run(drive)
    b = Simulator(models["built_in_exact"]).run(drive)
    out["max_ft_difference_plugin_vs_exact_N"] = float(np.max(np.abs(a.ft_N - b.ft_N)))
    return out


LINEAR_MOVES = {"interface_damping": (layout.P_CINT, "c_N_s_per_m", 30.0),
                "normal_coupling": (layout.P_KAPPA, "kappa", 0.1)}
"""Each effect moved onto linear terms: its kernel slot, its parameter, the value benchmarked."""


def _shs() -> Drive:
    """The slide-hold-slide of ``measure_library_moves`` (workbench kind: 2e-5 m/s, 1 and 3 s)."""
    return Drive.segments(300.0, [(5.0, 2e-5), (1.0, 0.0), (5.0, 2e-5), (3.0, 0.0), (5.0, 2e-5)])


def measure_linear_moves(duration_s: float = 3.0, repeats: int = 3) -> dict[str, float]:
    """Each library effect on the linear-term API against its coefficient set in the kernel."""
    out: dict[str, float] = {}
    drives = {"slide": Drive.constant(300.0, 1e-4, duration_s), "shs": _shs()}
    for name, (slot, param, value) in LINEAR_MOVES.items():
        api = Simulator(build_model("paper", effects=[name],
                                    effect_params={name: {param: value}}))
        built = Simulator(build_model("paper"))
        built._setup.cp[slot] = value  # the coefficient written into the kernel's vector directly
        assert not api._setup.terms.active and not built._setup.terms.active
        for dname, drive in drives.items():
            key = f"{name}_{dname}"
            t_built = _cpu_s(built, drive, repeats)
            t_api = _cpu_s(api, drive, repeats)
            out[f"{key}_built_in_cpu_s"] = t_built
            out[f"{key}_api_cpu_s"] = t_api
            out[f"{key}_api_speed_vs_built_in"] = t_built / t_api
            a = api.run(drive)
            b = built.run(drive)
            out[f"{key}_max_ft_difference_N"] = float(np.max(np.abs(a.ft_N - b.ft_N)))
            out[f"{key}_max_fn_difference_N"] = float(np.max(np.abs(a.fn_N - b.fn_N)))
    plugin = Simulator(build_model("paper", effects=[PluginDrag]))
    t_plugin = _cpu_s(plugin, drives["slide"], repeats)
    out["interface_damping_slide_as_force_term_cpu_s"] = t_plugin
    out["interface_damping_slide_force_term_speed_vs_built_in"] = (
        out["interface_damping_slide_built_in_cpu_s"] / t_plugin)
    lin = Simulator(build_model("paper", effects=[LinearSpring]))
    ft = Simulator(build_model("paper", effects=[ForceTermSpring]))
    out["spring_linear_cpu_s"] = _cpu_s(lin, drives["slide"], repeats)
    out["spring_force_term_cpu_s"] = _cpu_s(ft, drives["slide"], 3)
    out["spring_linear_speed_vs_force_term"] = (out["spring_force_term_cpu_s"]
                                                / out["spring_linear_cpu_s"])
    out["spring_linear_vs_force_term_max_ft_difference_N"] = float(np.max(np.abs(
        lin.run(drives["slide"]).ft_N - ft.run(drives["slide"]).ft_N)))
    return out


def measure_library_moves(repeats: int = 2) -> dict[str, float]:
    """CPU seconds of two library effects on their own path and on the general path."""
    drive = _shs()
    out: dict[str, float] = {}
    for name in ("rate_state", "presliding"):
        own = _cpu_s(Simulator(build_model("paper", effects=[name])), drive, repeats)
        general = _cpu_s(Simulator(build_model("paper", effects=[name, NoForce])), drive, repeats)
        out[f"{name}_own_path_cpu_s"] = own
        out[f"{name}_general_path_cpu_s"] = general
        out[f"{name}_general_slower_by"] = general / own
    return out


def library_agreement(duration_s: float = 3.0) -> dict[str, float]:
    """Each library effect on the general path against its exact path: max |dFt|, max |dt_start|."""
    drive = Drive.constant(300.0, 1e-4, duration_s)
    out: dict[str, float] = {}
    for name in sorted(LIBRARY):
        exact = Simulator(build_model("paper", effects=[name])).run(drive)
        general = Simulator(build_model("paper", effects=[name, NoForce])).run(drive)
        out[f"{name}_general_vs_exact_max_ft_N"] = float(np.max(np.abs(general.ft_N - exact.ft_N)))
        if len(general.events) == len(exact.events):
            dt = [abs(a.t_start_s - b.t_start_s) for a, b in zip(general.events, exact.events,
                                                                  strict=True)]
            out[f"{name}_general_vs_exact_max_slip_start_s"] = max(dt, default=0.0)
        else:
            out[f"{name}_general_vs_exact_max_slip_start_s"] = float("inf")
    return out


def main() -> int:
    quick = "--quick" in sys.argv
    res = measure(1.0 if quick else 3.0, 2 if quick else 5)
    res.update(measure_linear_moves(1.0 if quick else 3.0, 21))  # runs of ms: many repeats
    if "--library" in sys.argv:
        res.update(measure_library_moves())
        res.update(library_agreement())
    if "--json" in sys.argv:
        print(json.dumps(res, indent=2))
    else:
        for k, v in res.items():
            print(f"{k:40s} {v:.4g}")
    ok = res["plugin_speed_vs_built_in_general"] >= 0.5
    print(f"target plug-in >= 50 % of built in (same path): {'met' if ok else 'NOT met'}")
    moved = [k for k in res if k.endswith("_api_speed_vs_built_in")]
    ok_moved = all(res[k] >= 0.5 for k in moved)
    same = all(res[k] == 0.0 for k in res if k.endswith(("_max_ft_difference_N",
                                                         "_max_fn_difference_N"))
               and k.startswith(tuple(LINEAR_MOVES)))
    print(f"target library effects on linear terms >= 50 % of built in: "
          f"{'met' if ok_moved else 'NOT met'}; results {'the same bits' if same else 'DIFFER'}")
    return 0 if ok and ok_moved and same else 1


if __name__ == "__main__":
    sys.exit(main())

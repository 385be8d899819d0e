"""The vector one identification search moves (:mod:`rigctl.workbench.search`).

Its coordinates are the internal coordinates of :class:`~rigctl.workbench.identify.FreeParam`
(ln p for parameters whose bounds span more than a factor 20, p / scale otherwise), one per free
parameter, and, where an effect spreads the elements' thresholds, log2 of the element count N
(rounded to an integer where the model is built). Each coordinate has an initial standard deviation,
a quarter of the interval where its optimum is expected (the CMA-ES rule for sigma0, Hansen, *The
CMA Evolution Strategy: A Tutorial*, 2016, appendix B):

* base parameters read from the events (friction levels, series stiffness): within a factor
  :data:`BASE_FACTOR` of the start (ln p) or half their value (linear);
* mass and drive damping where the data do not state them: within :data:`DYNAMICS_FACTOR`;
* an effect's parameters over their *plausible range*: from the effect's off value to
  :data:`EFFECT_REACH` times its typical magnitude (the library default minus off, carried to the
  data's scale as :mod:`rigctl.workbench.data_scale` carries it), both signs where the bounds allow
  them; the spread starts are drawn there too. A log-scaled effect parameter with no typical
  deviation from off: within :data:`DYNAMICS_FACTOR` of its default;
* the element count: within its bounds :data:`N_ELEMENTS_RANGE`.

Every effect's off value is a point of the space exactly (:class:`ExactOff`): the start with the
effects off is the model without them bit for bit (the effect contract: at its off values an
effect leaves every output unchanged), so a search from a fitted model with an effect added can
always return to that fit. The element count's bounds include the model's own count for the same
reason.
"""

from __future__ import annotations

import math
from collections.abc import Collection, Mapping, Sequence
from dataclasses import dataclass, field, replace

import numpy as np
from scipy.stats import qmc

from rigctl.model.effects import Effect
from rigctl.records.dataset import Dataset
from rigctl.records.signals import FloatArray
from rigctl.workbench.data_scale import (
    NEAR_PRESET,
    scale_effect_values,
    scale_ratios,
    split_guessed,
)
from rigctl.workbench.data_start import campaign_scale
from rigctl.workbench.identify import DYNAMIC_PARAMS, FreeParam, free_params
from rigctl.workbench.model_choice import ModelChoice, effect_class, effect_of
from rigctl.workbench.search_pool import Point

BASE_FACTOR = NEAR_PRESET
"""A base parameter read from the events is expected within this factor of its data-scale start
(the factor within which the data-scale rule itself treats two scales as alike)."""
LINEAR_SPAN = 0.5
"""A linear base parameter (a friction level, p_slope) is expected within this fraction of its
start either way: the data-scale start reads the levels from the peaks and troughs directly."""
DYNAMICS_FACTOR = 100.0
"""Mass and drive damping not stated by the data, where the ringing does not tie the mass, are
expected within this factor of their start: that start only carries the preset's slip frequency
(880 Hz) and damping ratio to the data's stiffness, and rigs' slip frequencies differ by decades
(a spring-slider's tens of Hz to a stiff contact's kHz): a factor 10 in frequency either way is
a factor 100 in mass."""
EFFECT_REACH = NEAR_PRESET
"""An effect's plausible range reaches this many times its typical magnitude from off: the
library defaults are typical sizes, carried to the data's scale by ratios that are themselves
only trusted to a factor NEAR_PRESET."""
DAMPING_FOLLOWS_MASS = 0.5
"""d ln C0 / d ln M at a fixed damping ratio (C0 = 2 zeta sqrt(K0 M)): where the mass is spread
the drive damping moves with sqrt(M), as a mass that changes keeps the ringing's decay per cycle,
and the damping's own spread is the damping ratio's."""
MASS_LINE_STEP_DECADES = 0.5
"""The mass line's step (:meth:`SearchSpace.mass_line`): whether a model makes the measured slips
at all can hinge on its mass within a factor of a few (the spring-block's stick-slip boundary
depends on mass and damping at a given stiffness and friction law: Rice & Ruina 1983; Heslot et
al. 1994), a window that a few random draws over four decades of mass miss. Half a decade places
a point within a factor 10^0.25 = 1.8 of any mass on the line, 1.33 in the slip's frequency
(which goes as M^-1/2)."""
N_ELEMENTS_RANGE = (2, 64)
"""Element counts searched: from 2 (one element has no thresholds to spread) to 64, past which
each of the N steps of the stick ramp is under 2 % of it, inside a record's force scatter, while
a simulation's cost grows with N."""


@dataclass(frozen=True)
class ExactOff(FreeParam):
    """A free effect parameter whose off value maps to and from its internal coordinate exactly.

    ln and exp (or a division and a multiplication by the scale) do not round-trip every float:
    exp(ln 3) is 3.0000000000000004, and an effect at 3.0000000000000004 of its off value 3 is not
    off (its terms stay active, and an n_cycles of 3 plus an ulp is another model). At the
    internal coordinate of the off value this returns the off value itself."""

    off_p: float

    @property
    def off_u(self) -> float:
        return FreeParam.to_u(self, self.off_p)

    def to_p(self, u: float) -> float:
        if u == self.off_u:
            return self.off_p
        return FreeParam.to_p(self, u)


@dataclass(frozen=True)
class SearchSpace:
    """The search vector: ``free``'s internal coordinates, then log2 N where ``count``."""

    free: tuple[FreeParam, ...]
    std: FloatArray
    lower: FloatArray
    upper: FloatArray
    spread: dict[int, tuple[float, float]]
    """Coordinates whose start is a guess, not a reading of the data (effect parameters, mass and
    damping not stated, the element count, an unresolved stiffness split), and their plausible
    interval (internal units; for Kts of :attr:`series`, ln(Kts / K0)): the spread starts are
    drawn there."""
    count: bool
    off: dict[int, float] = field(default_factory=dict)
    """Effect coordinates and their off value (internal units, within the bounds): the start with
    the effects being added switched off (:meth:`switching_off`; all of them by default)."""
    follows: dict[int, tuple[int, float]] = field(default_factory=dict)
    """Coordinate i moves with coordinate j, slope a, where it is spread (``{i: (j, a)}``): its
    own spread is about that line. The drive damping C0 = 2 zeta sqrt(K0 M) follows the mass
    with slope 1/2 in logs (DAMPING_FOLLOWS_MASS): what is unknown of it on its own is the
    damping ratio zeta, not the C0 a new mass asks for; the initial-stage interface stiffness
    Kt0 follows Kts with slope 1 where the split is spread (both are the interface's)."""
    series: tuple[int, int] | None = None
    """(K0, Kts) coordinates where the split of the series stiffness between them is spread
    (:func:`~rigctl.workbench.data_scale.split_guessed`): a spread draw of Kts is one of the
    ratio, ln(Kts / K0), each ratio as likely as its inverse, and a point that sets Kts moves K0
    so that 1/K0 + 1/Kts keeps its start's value, the series stiffness the loading ramps read
    (at that series stiffness K_eff, Kts = K_eff (1 + Kts/K0))."""

    def prior_cov(self) -> FloatArray:
        """The covariance of where the optimum is expected: each coordinate's standard deviation,
        with the coordinates that follow another (:attr:`follows`) correlated with it."""
        T = np.eye(self.dim)
        for i, (j, a) in self.follows.items():
            T[i, j] = a
        return np.asarray(T @ np.diag(self.std**2) @ T.T, dtype=np.float64)

    def spread_point(self, x0: FloatArray, values: Mapping[int, float]) -> FloatArray:
        """``x0`` with the spread coordinates ``values`` set, and the coordinates that follow
        another moved with it (:attr:`follows`)."""
        x = np.array(x0, dtype=np.float64)
        for i, v in values.items():
            x[i] = v
        for i, (j, a) in self.follows.items():
            if j in values:
                x[i] += a * (values[j] - x0[j])
        if self.series is not None and self.series[1] in values and self.series[0] not in values:
            i0, i1 = self.series
            fk0, fkts = self.free[i0], self.free[i1]
            inv = 1.0 / fk0.to_p(float(x0[i0])) + 1.0 / fkts.to_p(float(x0[i1])) \
                - 1.0 / fkts.to_p(float(x[i1]))
            if inv > 0.0:  # else this Kts alone is softer than the series: K0 left as it is
                x[i0] = fk0.to_u(min(max(1.0 / inv, fk0.lower), fk0.upper))
        return x

    def with_values(self, x: FloatArray, values: Mapping[str, float],
                    coords: Collection[int] | None = None) -> FloatArray:
        """``x`` with its coordinates (those of ``coords`` only, where given) set to ``values``
        by parameter name, each within its bounds; names ``values`` lacks or holds no finite
        value of are left."""
        x = np.array(x, dtype=np.float64)
        for i, fp in enumerate(self.free):
            if (coords is None or i in coords) and fp.name in values \
                    and math.isfinite(values[fp.name]):
                x[i] = fp.to_u(min(max(values[fp.name], fp.lower), fp.upper))
        return x

    def mass_line(self, x0: FloatArray) -> list[FloatArray]:
        """``x0`` with the mass at every MASS_LINE_STEP_DECADES over its plausible interval
        (:attr:`spread`), the drive damping moved with it at ``x0``'s damping ratio
        (:attr:`follows`); none where the mass is no spread coordinate (stated, tied to a
        resolved ringing, or fixed by the rig description)."""
        i = next((k for k, fp in enumerate(self.free) if fp.name == "m_kg"), None)
        if i is None or i not in self.spread or not self.free[i].log:
            return []
        fp = self.free[i]
        lo, hi = self.spread[i]
        m0 = fp.to_p(float(x0[i]))
        out = []
        for k in range(-8, 9):
            u = fp.to_u(m0 * 10.0 ** (k * MASS_LINE_STEP_DECADES))
            if k != 0 and lo - 1e-9 <= u <= hi + 1e-9:  # the interval's ends to rounding
                out.append(np.clip(self.spread_point(x0, {i: u}), self.lower, self.upper))
        return out

    def switching_off(self, effects: Collection[str]) -> SearchSpace:
        """This space with only ``effects``' coordinates in :attr:`off`: a model that already has
        fitted effects and gets more keeps its own at their values in the start with the new ones
        off, which is then that model itself."""
        keep = {i: u for i, u in self.off.items() if effect_of(self.free[i].name) in effects}
        return replace(self, off=keep)

    def off_point(self, x: FloatArray) -> FloatArray:
        """``x`` with the effects of :attr:`off` at their off values: from a start that is a
        fitted model with effects added, exactly that fit."""
        out = np.array(x, dtype=np.float64)
        for i, u in self.off.items():
            out[i] = u
        return out

    @property
    def dim(self) -> int:
        return int(self.std.shape[0])

    def point(self, x: FloatArray) -> Point:
        """The evaluated point of vector ``x``: the free coordinates and the rounded count."""
        x = np.clip(np.asarray(x, dtype=np.float64), self.lower, self.upper)
        n_free = len(self.free)
        n = round(2.0 ** float(x[n_free])) if self.count else None
        return Point(x[:n_free].copy(), n)

    def sobol_points(self, x0: FloatArray, idx: Sequence[int], n: int,
                     seed: int) -> list[FloatArray]:
        """``x0`` with coordinates ``idx`` (of :attr:`spread`) set to scrambled Sobol points over
        their plausible intervals (``scipy.stats.qmc``), and those that follow them moved with
        them: ``n`` rounded up to a power of two, at least 2 (a balanced Sobol sequence)."""
        m = max(1, math.ceil(math.log2(max(n, 1))))
        unit = qmc.Sobol(d=len(idx), scramble=True, seed=seed).random_base2(m)
        lo = np.array([self.spread[i][0] for i in idx])
        hi = np.array([self.spread[i][1] for i in idx])
        return [self.spread_point(x0, {i: self._drawn(i, float(t), x0)
                                       for i, t in zip(idx, lo + row * (hi - lo), strict=True)})
                for row in unit]

    def _drawn(self, i: int, t: float, x0: FloatArray) -> float:
        """Coordinate ``i``'s value for a draw ``t`` from its :attr:`spread` interval: ``t``
        itself, except for Kts of :attr:`series`, drawn as ln(Kts / K0) at ``x0``'s series
        stiffness."""
        if self.series is None or i != self.series[1]:
            return t
        i0, i1 = self.series
        f0, f1 = self.free[i0], self.free[i1]
        k_eff = 1.0 / (1.0 / f0.to_p(float(x0[i0])) + 1.0 / f1.to_p(float(x0[i1])))
        return f1.to_u(min(max(k_eff * (1.0 + math.exp(t)), f1.lower), f1.upper))

    def values(self, x: FloatArray) -> dict[str, float]:
        """Parameter values of vector ``x`` (the element count included where searched)."""
        p = self.point(x)
        out = {fp.name: fp.to_p(float(u)) for fp, u in zip(self.free, p.u, strict=True)}
        if p.n_elements is not None:
            out["n_elements"] = float(p.n_elements)
        return out

    def vector(self, choice: ModelChoice) -> FloatArray:
        """``choice``'s values as a vector (clipped to the bounds)."""
        table = {p.name: p.value for p in choice.parameter_table()}
        x = [fp.to_u(min(max(table[fp.name], fp.lower), fp.upper)) for fp in self.free]
        if self.count:
            x.append(math.log2(table["n_elements"]))
        return np.clip(np.array(x, dtype=np.float64), self.lower, self.upper)


def build_space(dataset: Dataset, choice: ModelChoice, ref: ModelChoice,
                spreads_elements: bool) -> SearchSpace:
    """The search space of ``choice`` on ``dataset``; ``ref`` (the data-scale start, or the choice
    itself) sets the linear parameters' scales and the mass and damping's bounds."""
    rig = dataset.rig
    table = {p.name: p for p in ref.parameter_table()}
    names = [n for n, p in table.items() if p.identify and n not in rig.fixed]
    names += [n for n in DYNAMIC_PARAMS if n not in names and n not in rig.fixed
              and not (n == "m_kg" and dataset.mass_from_ringing)]
    free = free_params(ref, names, rig=rig)
    ranges = effect_ranges(dataset, ref, [fp for fp in free if "." in fp.name])
    out: list[FreeParam] = []
    std: list[float] = []
    spread: dict[int, tuple[float, float]] = {}
    off: dict[int, float] = {}
    for i, fp in enumerate(free):
        if fp.name in ranges:
            lo, hi, typical, p_off = ranges[fp.name]
            if not fp.log:  # scaled by the effect's own size, not by its value or bounds
                fp = replace(fp, scale=typical)
            u_lo, u_hi = sorted((fp.to_u(lo), fp.to_u(hi)))
            spread[i] = (u_lo, u_hi)
            if math.isfinite(p_off):  # inside the bounds by the effect contract; a rig's
                # narrower bounds that exclude it leave the nearest value they allow
                fp = ExactOff(fp.name, fp.lower, fp.upper, fp.log, fp.scale,
                              min(max(p_off, fp.lower), fp.upper))
                off[i] = fp.off_u
            std.append(0.25 * (u_hi - u_lo))
        elif fp.name in DYNAMIC_PARAMS and fp.log:
            v = table[fp.name].value
            spread[i] = (fp.to_u(max(v / DYNAMICS_FACTOR, fp.lower)),
                         fp.to_u(min(v * DYNAMICS_FACTOR, fp.upper)))
            std.append(0.25 * (spread[i][1] - spread[i][0]))
        else:
            std.append(0.5 * math.log(BASE_FACTOR) if fp.log else LINEAR_SPAN / 2.0)
        out.append(fp)
    lower = [fp.u_bounds[0] for fp in out]
    upper = [fp.u_bounds[1] for fp in out]
    follows: dict[int, tuple[int, float]] = {}
    names_at = {fp.name: i for i, fp in enumerate(out)}
    if all(n in names_at and out[names_at[n]].log and names_at[n] in spread
           for n in DYNAMIC_PARAMS):
        follows[names_at["c0_N_s_per_m"]] = (names_at["m_kg"], DAMPING_FOLLOWS_MASS)
    series = _spread_split(dataset, out, spread, std, follows)
    count = spreads_elements and "n_elements" not in rig.fixed
    if count:
        lo_n, hi_n = (math.log2(n) for n in N_ELEMENTS_RANGE)
        own = [math.log2(max(t["n_elements"].value, 1.0)) for t in
               ({p.name: p for p in choice.parameter_table()}, table)]
        lower.append(min(lo_n, *own))  # the model's own count stays a point of the space
        upper.append(max(hi_n, *own))
        spread[len(out)] = (lo_n, hi_n)
        std.append(0.25 * (hi_n - lo_n))
    return SearchSpace(tuple(out), np.array(std), np.array(lower), np.array(upper), spread, count,
                       off, follows, series)


def _spread_split(dataset: Dataset, free: Sequence[FreeParam],
                  spread: dict[int, tuple[float, float]], std: list[float],
                  follows: dict[int, tuple[int, float]]) -> tuple[int, int] | None:
    """Where the data do not read the split of the series stiffness K_eff between the drive
    spring K0 and the interface Kts (:func:`~rigctl.workbench.data_scale.split_guessed`), Kts's
    start is a guess and Kts is a spread coordinate like the mass: drawn as ln(Kts / K0) over
    the ratio's plausible interval (:attr:`SearchSpace.series`), K0 moving with it at the series
    stiffness of the start and Kt0 in proportion (:attr:`SearchSpace.follows`); its standard
    deviation a quarter of the interval of Kts = K_eff (1 + Kts/K0) that ratio spans. A split the
    probes do not resolve is otherwise searched only within BASE_FACTOR of its guess, decades
    from a rig whose interface is neither rigid nor the preset's. Sets ``spread``, ``std`` and
    ``follows`` in place; returns the (K0, Kts) coordinates, or None."""
    at = {fp.name: i for i, fp in enumerate(free)}
    i0, i1 = at.get("k0_N_per_m"), at.get("kts_N_per_m")
    if i0 is None or i1 is None or not (free[i0].log and free[i1].log):
        return None  # a stiffness the rig description states: the split follows from it
    scale = campaign_scale(dataset)
    ratios = split_guessed(scale)
    if ratios is None:
        return None
    fp = free[i1]
    k_eff = scale.k_eff_N_per_m
    lo, hi = (fp.to_u(min(max(k_eff * (1.0 + r), fp.lower), fp.upper)) for r in ratios)
    if not hi > lo:
        return None
    spread[i1] = (math.log(ratios[0]), math.log(ratios[1]))
    std[i1] = 0.25 * (hi - lo)
    j = at.get("kt0_N_per_m")
    if j is not None and free[j].log and j not in spread:
        follows[j] = (i1, 1.0)
    return (i0, i1)


def effects_at_data_scale(dataset: Dataset, choice: ModelChoice, effects: Collection[str],
                          identified: bool = False) -> ModelChoice:
    """``choice`` with the fixed dimensional parameters of ``effects`` (``identify=False`` with a
    ``scales_with`` quantity: a reference load, a reference velocity, a contact age) carried to the
    data's scale as :func:`~rigctl.workbench.data_scale.scale_effect_values` carries them (only
    where the data lie more than a factor NEAR_PRESET from the preset), except what the rig
    description fixes. With ``identified``, the identified ones too: from the library defaults,
    the effects at their typical size on these data (:func:`typical_point`).

    No coordinate of the search moves these, so a library default at the preset's scale stays
    wrong by the scale ratio: a power law of the load referred to the preset's 300 N on a 10 N rig
    multiplies the friction levels by (10/300)^alpha, a factor of 4 at alpha 0.4, which the base's
    levels would have to undo before the effect could show its gain. At their off values the
    effects leave every output unchanged whatever these are, so the model without them is the
    same model."""
    if not effects:
        return choice
    scale = campaign_scale(dataset)
    if not scale.usable:
        return choice
    prefixes = tuple(f"{e}." for e in effects)
    params = choice.parameter_table()
    table = [(p.name, p.value, p.lower, p.upper, p.scales_with)
             for p in params
             if p.name.startswith(prefixes) and p.scales_with and (identified or not p.identify)
             and p.name not in dataset.rig.fixed]
    if not table:
        return choice
    base = {p.name: p.value for p in params if "." not in p.name}
    rate = float(np.median([r.sample_rate_hz for r in dataset.runs]))
    changed = scale_effect_values(table, scale_ratios(scale, base, rate))
    return choice.with_values(changed) if changed else choice


def typical_point(dataset: Dataset, choice: ModelChoice,
                  effects: Collection[str]) -> ModelChoice | None:
    """``choice`` with ``effects`` at their library defaults carried to the data's scale (every
    dimensional parameter, :func:`effects_at_data_scale`), the rest of the model as it is; None
    where ``effects`` is empty.

    The library default is each effect's typical size (docs/effects.md), the centre of the prior
    its plausible range is drawn around: the one point of that range most likely to show the
    effect, so screens and searches evaluate it as well as the spread points. It matters most
    where an effect's gain lies in a narrow region of several coordinates at once (a load exponent
    on both friction levels: the levels fit only where the two are near each other), which a few
    scattered points miss."""
    if not effects:
        return None
    values = {k: v for k, v in choice.values.items()
              if effect_of(k) not in effects or k in dataset.rig.fixed}
    plain = ModelChoice(choice.base, choice.effects, values, choice.effect_files)
    return effects_at_data_scale(dataset, plain, effects, identified=True)


def effect_ranges(dataset: Dataset, choice: ModelChoice,
                  free: list[FreeParam]) -> dict[str, tuple[float, float, float, float]]:
    """Each free effect parameter's plausible range (lower, upper) in parameter units, its
    typical size (the module docstring) and its off value (NaN where the effect states none)."""
    table = {p.name: p for p in choice.parameter_table()}
    base = {n: p.value for n, p in table.items() if "." not in n}
    scale = campaign_scale(dataset)
    ratios: Mapping[str, float] = {}
    if scale.usable:
        rate = float(np.median([r.sample_rate_hz for r in dataset.runs]))
        ratios = scale_ratios(scale, base, rate)
    out: dict[str, tuple[float, float, float, float]] = {}
    for effect in sorted({effect_of(fp.name) for fp in free} - {""}):
        cls = effect_class(effect, choice.effect_files)
        if cls is None:
            continue
        eff: Effect = cls()
        try:
            offs = eff.off_values(base)
        except NotImplementedError:
            offs = {}
        defaults = eff.default_values(base)
        rows = [(f"{effect}.{k}", v, table[f"{effect}.{k}"].lower, table[f"{effect}.{k}"].upper,
                 table[f"{effect}.{k}"].scales_with) for k, v in defaults.items()
                if f"{effect}.{k}" in table]
        defaults.update({k.split(".", 1)[1]: v for k, v in scale_effect_values(rows,
                                                                               ratios).items()})
        for fp in free:
            if not fp.name.startswith(effect + "."):
                continue
            key = fp.name.split(".", 1)[1]
            default = defaults.get(key, table[fp.name].value)
            off = offs.get(key, default)
            typical = default - off
            if typical == 0.0 or (fp.log and off <= 0.0):
                if not fp.log:  # no size to go by: a quarter of the allowed range
                    typical = 0.25 * (fp.upper - fp.lower)
                else:
                    lo = max(default / DYNAMICS_FACTOR, fp.lower)
                    hi = min(default * DYNAMICS_FACTOR, fp.upper)
                    out[fp.name] = (lo, hi, default, offs.get(key, math.nan))
                    continue
            signed = fp.lower < off < fp.upper and fp.lower < 0.0
            reach = EFFECT_REACH * abs(typical)
            lo = off - reach if signed else min(off, off + EFFECT_REACH * typical)
            hi = off + reach if signed else max(off, off + EFFECT_REACH * typical)
            out[fp.name] = (max(lo, fp.lower), min(hi, fp.upper), abs(typical),
                            offs.get(key, math.nan))
    return out

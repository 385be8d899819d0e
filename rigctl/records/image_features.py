"""The model's stress distribution against the contact images: P(i, t) vs the measured P(k, t).

Han et al. 2022, Sec. 5.1 (Fig. 13): "the contact area is divided into 10 parts along the x
direction, and the intensity proportion of local contact image is calculated as the equivalent
stress distribution P(k, t)"; Sec. 5.2: P(i) is P_linear in the initial stage (the back end carries
less) and P_uniform in the stable stage (``rigctl.model.effects.stress_evolution``). When a run
file has camera frames, two numbers per run compare the model's P(i, t) with the images (docs/
reading-records.md, "Contact images"):

``p_tilt_initial`` - **the initial stage's back-end unloading**, as a tilt. A part's light is
a texture-dependent, nonlinear function of its pressure (a few asperities per part: on the
simulated camera the light of single parts grows as Fn^0.6 ... Fn^5), so a part's share of the light
is not its share of the load. The reading assumes only what the paper's does (Sec. 3.2: the contact
image represents the stress), in its weakest form: **equal light in a part means equal pressure
there**. Frames of the initial stage before the contact slides (the normal loading and the rest
before motion; Ft under ``A_FT_FRACTION`` of the first peak) give part k's light against Fn with
pressure ``Fn c_A(k)``; frames of the stable stage (the slide and the release under load) with
pressure ``Fn c_B(k)``. Where the two curves overlap in light, the forces at equal light give the
ratio ``r(k) = c_A(k) / c_B(k) = F_B / F_A`` (median over the matched frames). The model's r(k) is
the ratio of its own shares P(k) over the same frames (its stage at each frame time, from the
simulation: exact, no extra engine work). The compared number is the least-squares slope of r(k)
against ``2 xi_k - 1`` (xi_k the part's centre) over the inner parts (2-9) where the measurement
has r(k) (:func:`tilt_of`): for ``P_linear`` over ``P_uniform`` it is ``p_slope`` itself. Its
scatter is the slope's standard error from the parts' scatter about the line (the texture's
reading error), at least ``TILT_FLOOR``.

``p_var_stable`` - **the small stable-stage variation** (Fig. 13c: "the change range of stress
distribution in the stable stage is small"): the change of the back fifth's share P(1) + P(2)
between the frames of the upper and lower third of Ft in the stable stage at the slide's load
(upper minus lower mean), in its standard error from the frame-to-frame scatter. The model's is
the same difference of its own shares over the same frames (0 for ``stress_evolution``).

Frames are read once, when the dataset is loaded, through the streamed intensity pass of
:mod:`rigctl.records.contact_intensity` (bounded memory: 4 bytes per frame and profile bin); only
the frame times and per-part numbers are kept. A run without frames has no image feature.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from numpy.typing import NDArray
from scipy.optimize import isotonic_regression

from rigctl.data import DataError, MeasuredRun
from rigctl.model import SimResult
from rigctl.records.drive_profile import fn_apart_N
from rigctl.records.feature_info import IMAGE_FEATURES
from rigctl.records.features import EventTable, ReadSettings
from rigctl.records.signals import FloatArray

N_PARTS = 10
"""Parts of the contact along x (Sec. 5.1)."""
A_FT_FRACTION = 0.05
"""Initial-stage frames taken as 'before the contact slides': Ft under this fraction of the first
peak. The back element of P_linear starts to slide at (1 - s (1 - 1/N)) of the threshold, 10 % at
the largest slope s = 0.999: 5 % is below that for any s."""
MIN_SPAN = 0.2
"""A light-vs-Fn curve is inverted only where its frames span at least this fraction of its
largest Fn (a rest at one load is a point, not a curve)."""
MAX_GAP = 0.05
"""A light is read on a curve only between two of its points at most this fraction of its largest
Fn apart (15 N at 300 N): a release over 1.5 s seen at 20 frames/s has 70 N between frames, and a
straight line across such a gap misreads a part's nonlinear light by several percent."""
LOCAL_WINDOW = 0.04
"""Half width (fraction of the curve's largest Fn: 12 N at 300 N) of the frames a reading's line
is fitted to."""
MIN_MATCHES = 3
"""Frames of equal light a part needs for its ratio r(k)."""
MIN_LIGHT = 0.1
"""Light below this fraction of a part's largest on the inverted curve is not matched (too near
the dark level for its Fn to be read)."""
MIN_PARTS = 4
"""Parts with r(k) needed for the tilt."""
TILT_FLOOR = 0.02
"""Scatter floor of the tilt: what reading the load from light at 10 parts can do, calibrated on
simulated runs whose truth is known (a calibration, not a derivation: docs/decisions.md); a
standard error from 5-8 parts' scatter can come out smaller than that."""
VAR_FLOOR = 0.001
"""Scatter floor of the stable-stage change of the back share (a share: 0.1 % of the contact)."""
STABLE_LOAD_TOL = 0.05
"""Stable frames within this fraction of the slide's median Fn count for the stable variation."""


@dataclass(frozen=True)
class ImageFeatures:
    """What the frames of one run say, reduced to the frames and numbers the comparison needs."""

    t_a_s: FloatArray
    """Times (from the run's first sample) of the initial-stage frames before the contact slides."""
    t_b_s: FloatArray
    """Times of the loaded stable-stage frames."""
    b_used: NDArray[np.bool_]
    """(N_PARTS, len(t_b_s)): the stable frames each part matched (and the A frames: all)."""
    r_meas: FloatArray
    """Per part: the ratio r(k) = c_A / c_B read at equal light (NaN where not read)."""
    tilt: float
    tilt_sigma: float
    t_lo_s: FloatArray
    """Stable frames at the slide's load in the lower third of Ft."""
    t_hi_s: FloatArray
    """... and in the upper third."""
    var: float
    var_sigma: float
    n_frames: int

    def measured(self) -> dict[str, float]:
        return dict(zip(IMAGE_FEATURES, (self.tilt, self.var), strict=True))

    def sigma(self) -> dict[str, float]:
        return dict(zip(IMAGE_FEATURES, (self.tilt_sigma, self.var_sigma), strict=True))

    def to_json(self) -> dict[str, object]:
        return {"n_frames": self.n_frames, "n_initial_frames": int(self.t_a_s.size),
                "n_stable_frames": int(self.t_b_s.size), "r_measured": self.r_meas.tolist(),
                "p_tilt_initial": self.tilt, "p_tilt_initial_sigma": self.tilt_sigma,
                "p_var_stable": self.var, "p_var_stable_sigma": self.var_sigma}


def _curve(f: FloatArray, i: FloatArray) -> tuple[FloatArray, FloatArray] | None:
    """Light against Fn as an increasing curve, or None where the frames do not span a curve
    (MIN_SPAN). The light of a part at one Fn jitters by its read noise (1-2 % per frame on the
    simulated camera); the curve is the least-squares increasing fit (isotonic regression,
    ``scipy.optimize.isotonic_regression``), whose plateaus are then collapsed to their middle: a
    running maximum would follow the noise up on a densely sampled ramp."""
    ok = np.isfinite(f) & np.isfinite(i)
    f, i = f[ok], i[ok]
    if f.size < MIN_MATCHES or f.max() - f.min() < MIN_SPAN * max(abs(f.max()), 1e-12):
        return None
    o = np.argsort(f)
    fs = f[o]
    mono = np.asarray(isotonic_regression(i[o]).x, dtype=np.float64)
    levels, start, count = np.unique(mono, return_index=True, return_counts=True)
    mid = 0.5 * (fs[start] + fs[start + count - 1])  # a plateau's Fn: the middle of its frames
    return levels, mid


def _invert(curve: tuple[FloatArray, FloatArray] | None, light: FloatArray,
            f_pts: FloatArray | None = None, i_pts: FloatArray | None = None) -> FloatArray:
    """Fn on ``curve`` at each ``light`` (NaN outside the curve or too near the dark level).

    With the curve's frames (``f_pts``, ``i_pts``) the first reading is refined by the straight
    line fitted to the frames within LOCAL_WINDOW of it: one frame's light jitters by its read
    noise (1-3 % for a part on the simulated camera, 5 N of a 300 N ramp), a line through the
    frames around it by less."""
    out = np.full(light.shape, np.nan)
    if curve is None or curve[0].size < 2:
        return out
    lc, fc = curve
    ok = (light > max(lc[0], MIN_LIGHT * lc[-1])) & (light < lc[-1])
    # only between curve points close in Fn: a fast ramp seen by a few frames is no curve there
    j = np.clip(np.searchsorted(lc, light), 1, lc.size - 1)
    ok &= np.diff(fc)[j - 1] <= MAX_GAP * float(fc[-1])
    out[ok] = np.interp(light[ok], lc, fc)
    if f_pts is None or i_pts is None:
        return out
    half = LOCAL_WINDOW * float(fc[-1])
    good = np.isfinite(f_pts) & np.isfinite(i_pts)
    fp, ip = f_pts[good], i_pts[good]
    for k in np.flatnonzero(ok):
        near = np.abs(fp - out[k]) <= half
        if np.count_nonzero(near) >= 3 and np.ptp(fp[near]) > 0:
            slope, icpt = np.polyfit(fp[near], ip[near], 1)
            if slope > 0:
                out[k] = (light[k] - icpt) / slope
    return out


def equal_light_ratio(f_a: FloatArray, i_a: FloatArray, f_b: FloatArray, i_b: FloatArray
                      ) -> tuple[float, NDArray[np.bool_]]:
    """r = c_A / c_B of one part from two families of frames (see the module docstring).

    Each B frame's light is read on the A curve (Fn_A at equal light: r = Fn_B / Fn_A), and each A
    frame's on the B curve (r = Fn_B / Fn_A again); r is the median of all. Returns r (NaN with
    fewer than MIN_MATCHES matches) and which B frames matched (directly or as a curve point).
    """
    fa_star = _invert(_curve(f_a, i_a), i_b, f_a, i_a)  # B frames on the A curve
    curve_b = _curve(f_b, i_b)
    fb_star = _invert(curve_b, i_a, f_b, i_b)  # A frames on the B curve
    with np.errstate(invalid="ignore", divide="ignore"):
        ratios = np.concatenate([f_b / fa_star, fb_star / f_a])
    ratios = ratios[np.isfinite(ratios) & (ratios > 0)]
    used = np.isfinite(fa_star)
    if np.isfinite(fb_star).any():
        used = used | np.isfinite(f_b) & np.isfinite(i_b)
    if ratios.size < MIN_MATCHES:
        return math.nan, used
    return float(np.median(ratios)), used


def tilt_of(r: FloatArray) -> tuple[float, float]:
    """Least-squares slope of r(k) against 2 xi_k - 1 over the inner parts with a value, and its
    standard error from their scatter about the line (NaN with fewer than MIN_PARTS parts).

    The end parts are left out: the model's shares are per element, and what a continuous
    distribution does within the end halves of the end elements is not part of the model (the
    simulated camera holds it flat there, so part 1 reads 0.24 where element 0 has 0.19)."""
    xi = (np.arange(r.size) + 0.5) / r.size
    ok = np.isfinite(r)
    ok[[0, -1]] = False
    if np.count_nonzero(ok) < MIN_PARTS:
        return math.nan, math.nan
    u = 2.0 * xi[ok] - 1.0
    slope, icpt = np.polyfit(u, r[ok], 1)
    res = r[ok] - (slope * u + icpt)
    sxx = float(np.sum((u - u.mean()) ** 2))
    se = math.sqrt(float(np.sum(res**2)) / (u.size - 2) / sxx)
    return float(slope), se


def part_matrix(n_elements: int, n_parts: int = N_PARTS) -> FloatArray:
    """(n_elements, n_parts): the share of element i (covering [i/N, (i+1)/N)) in part k."""
    from rigctl.records.contact_intensity import bin_matrix  # frames machinery loaded on use

    return np.asarray(bin_matrix(n_elements, n_parts), dtype=np.float64)


def _stage_windows(t: FloatArray, ft: FloatArray, fn: FloatArray, apart: float,
                   events: EventTable, settle_s: float) -> tuple[NDArray[np.bool_], NDArray[np.bool_],
                                                                 NDArray[np.bool_], NDArray[np.bool_]]:
    """Per frame: in A (initial stage, before sliding), in B (loaded stable stage), and in the
    lower and upper third of Ft of the stable frames at the slide's load."""
    a = np.zeros(t.size, dtype=bool)
    b = np.zeros(t.size, dtype=bool)
    lo = np.zeros(t.size, dtype=bool)
    hi = np.zeros(t.size, dtype=bool)
    loaded = fn > apart
    for j in np.flatnonzero(events.stage == 0):
        t0 = float(events.t_drop_s[j])
        peak = float(events.features["peak_N"][j])
        if not math.isfinite(peak):
            peak = float(np.max(np.abs(ft[(t <= t0)]))) if np.any(t <= t0) else math.nan
        before = np.flatnonzero(~loaded & (t < t0))
        t_start = float(t[before[-1]]) if before.size else -math.inf
        after = np.flatnonzero(~loaded & (t > t0))
        t_stop = float(t[after[0]]) if after.size else math.inf
        a |= loaded & (t > t_start) & (t < t0) & (np.abs(ft) < A_FT_FRACTION * abs(peak))
        stable = loaded & (t > t0 + settle_s) & (t < t_stop)
        b |= stable
        fn_slide = float(np.median(fn[stable])) if stable.any() else math.nan
        at_load = stable & (np.abs(fn - fn_slide) < STABLE_LOAD_TOL * fn_slide)
        if np.count_nonzero(at_load) >= 6:
            q1, q2 = np.quantile(ft[at_load], [1 / 3, 2 / 3])
            lo |= at_load & (ft <= q1)
            hi |= at_load & (ft >= q2)
    return a, b, lo, hi


def read_image_features(run: MeasuredRun, events: EventTable, read: ReadSettings
                        ) -> tuple[ImageFeatures | None, str]:
    """The image features of a run file with frames; (None, why) when there are none."""
    path = Path(run.source) if run.source else None
    if path is None or path.suffix.lower() not in (".h5", ".hdf5") or not path.is_file():
        return None, "no camera frames (not a run file)"
    from rigctl.records.contact_intensity import find_contact_region, stream_intensity
    from rigctl.records.contact_profile import p_bins
    from rigctl.storage.reader import RunReader

    try:
        with RunReader(path) as reader:
            if reader.n_frames < 2:
                return None, "no camera frames"
            region = find_contact_region(reader)
            ci = stream_intensity(reader, region)
    except (DataError, OSError, KeyError, ValueError, RuntimeError) as exc:
        # frames that cannot be read leave the run without an image feature, not without a compare
        return None, f"frames unusable ({exc})"
    t = ci.t_s - float(run.t_s[0])
    ok = np.isfinite(t) & np.isfinite(ci.ic)
    ft = np.interp(t, run.t_s - run.t_s[0], run.ft_N)
    fn = np.interp(t, run.t_s - run.t_s[0], run.fn_N)
    a, b, lo, hi = _stage_windows(t, ft, fn, fn_apart_N(run.fn_N), events, read.settle_s)
    a &= ok
    b &= ok
    if not a.any() or not b.any():
        return None, "frames without both an initial stage from rest and a stable stage"
    prof = np.clip(np.asarray(ci.profile, dtype=np.float64), 0.0, None)
    light = prof.reshape(prof.shape[0], N_PARTS, -1).sum(axis=2)  # each part's light
    r = np.full(N_PARTS, np.nan)
    used = np.zeros((N_PARTS, int(np.count_nonzero(b))), dtype=bool)
    for k in range(N_PARTS):
        r[k], used[k] = equal_light_ratio(fn[a], light[a, k], fn[b], light[b, k])
    tilt, se = tilt_of(r)
    if not math.isfinite(tilt):
        return None, (f"the frames give the load ratio of only {np.count_nonzero(np.isfinite(r))} "
                      f"of {N_PARTS} parts (no normal loading or release seen by the camera?)")
    back = p_bins(ci.profile)[:, :2].sum(axis=1)
    lo &= ok & np.isfinite(back)
    hi &= ok & np.isfinite(back)
    var, var_se = math.nan, math.nan
    if np.count_nonzero(lo) >= 3 and np.count_nonzero(hi) >= 3:
        var = float(np.mean(back[hi]) - np.mean(back[lo]))
        var_se = math.sqrt(float(np.var(back[hi], ddof=1)) / np.count_nonzero(hi)
                           + float(np.var(back[lo], ddof=1)) / np.count_nonzero(lo))
    return ImageFeatures(
        t_a_s=t[a], t_b_s=t[b], b_used=used, r_meas=r, tilt=tilt,
        tilt_sigma=max(se, TILT_FLOOR), t_lo_s=t[lo], t_hi_s=t[hi], var=var,
        var_sigma=max(var_se, VAR_FLOOR) if math.isfinite(var_se) else math.nan,
        n_frames=ci.n_frames,
    ), ""


def model_parts(res: SimResult, t_s: FloatArray) -> FloatArray:
    """The model's P(k) at times ``t_s`` (rows): its stage's shares P(i) summed into the parts."""
    if t_s.size == 0:
        return np.zeros((0, N_PARTS))
    i = np.clip(np.searchsorted(res.t_s, t_s), 0, res.n_samples - 1)
    p_el = res.p_tables[res.stage[i].astype(np.intp)]
    out: FloatArray = p_el @ part_matrix(p_el.shape[1])
    return out


def model_ratios(res: SimResult, img: ImageFeatures) -> FloatArray:
    """The model's r(k): its mean P(k) over the initial frames over its mean P(k) over the stable
    frames part k matched (NaN where the measurement has no r(k))."""
    pa = model_parts(res, img.t_a_s).mean(axis=0)
    pb = model_parts(res, img.t_b_s)
    r = np.full(N_PARTS, np.nan)
    for k in range(N_PARTS):
        if math.isfinite(img.r_meas[k]) and img.b_used[k].any():
            r[k] = pa[k] / float(np.mean(pb[img.b_used[k], k]))
    return r


def model_image_numbers(res: SimResult, img: ImageFeatures) -> dict[str, float]:
    """The model's image features, read over the measurement's frames as the measurement's are."""
    tilt, _ = tilt_of(model_ratios(res, img))
    var = math.nan
    if img.t_lo_s.size and img.t_hi_s.size:
        back_lo = model_parts(res, img.t_lo_s)[:, :2].sum(axis=1)
        back_hi = model_parts(res, img.t_hi_s)[:, :2].sum(axis=1)
        var = float(np.mean(back_hi) - np.mean(back_lo))
    return dict(zip(IMAGE_FEATURES, (tilt, var), strict=True))

"""Index layout of the flat arrays the compiled kernel works on.

The kernel (:mod:`rigctl.model.kernel`) is compiled with numba, so the model reaches it as small
typed arrays: one float parameter vector, the element weight table, one float and one integer state
vector, the input knots, the output table and the event table. This module is the single source of
truth for what each slot, row and column means; :mod:`rigctl.model.spec` fills the parameter vector
and the weight table from the typed parameters and effects.
"""

from __future__ import annotations

# --- parameter vector (float64) ---------------------------------------------------------------
P_M = 0  # specimen mass M [kg]
P_C0 = 1  # drive damping C0 [N s/m]
P_K0 = 2  # drive stiffness K0 [N/m]
P_KTS = 3  # interface tangential stiffness, stable stage Kts [N/m]
P_MUS = 4  # static friction coefficient, stable stage mu_s [-]
P_MUK = 5  # kinetic friction coefficient mu_k [-]
P_KT0 = 6  # interface tangential stiffness, initial stage Kt0 [N/m]
P_MUSMAX = 7  # maximum static friction coefficient, initial stage mu_s,max [-]
P_PSLOPE = 8  # slope of P_linear across the contact (0 = uniform) [-]
P_VS = 9  # Stribeck velocity vs [m/s] (0 = off)
P_SD = 10  # Stribeck exponent d [-]
P_RS_A = 11  # rate-and-state direct effect a [-]
P_RS_B = 12  # rate-and-state evolution effect b [-]
P_RS_DC = 13  # rate-and-state characteristic slip Dc [m]
P_RS_VREF = 14  # rate-and-state reference velocity [m/s]
P_ALPHA_S = 15  # load-dependent friction exponent on mu_s [-]
P_ALPHA_K = 16  # load-dependent friction exponent on mu_k [-]
P_FNREF_MU = 17  # reference normal force of the friction power law [N]
P_BETA0 = 18  # load-dependent stiffness exponent on Kt0 [-]
P_BETAS = 19  # load-dependent stiffness exponent on Kts [-]
P_FNREF_K = 20  # reference normal force of the stiffness power law [N]
P_KT_MULT = 21  # multiplier on the stable stiffness (contact degradation, set per cycle) [-]
P_DMU_S = 22  # additive change of mu_s (wear, set per slip) [-]
P_DMU_K = 23  # additive change of mu_k (wear, set per slip) [-]
P_SPREAD = 24  # presliding (Iwan) spread of element static thresholds [-]
P_CINT = 25  # interface viscous damping [N s/m]
P_KAPPA = 26  # normal coupling: dFn / dF_drive [-]
P_TAU_S = 27  # force-sensor time constant [s] (0 = ideal sensor)
P_KPAR = 28  # spring from the slider to the frame, in parallel with the drive (linear terms) [N/m]
P_XPAR = 29  # the slider's position X at which that spring is relaxed: X at t = 0 (per run) [m]
N_PARAMS = 30

# --- float state vector -----------------------------------------------------------------------
S_T = 0  # time [s]
S_X = 1  # specimen position X [m]
S_V = 2  # specimen velocity [m/s]
S_YF = 3  # sensor filter output [N]
S_THETA = 4  # rate-and-state state variable theta [s]
S_SLIP_CUM = 5  # cumulative global-slip distance [m]
S_X_INIT = 6  # X at t = 0 (delta reference) [m]
S_K_USED = 7  # per-element stiffness the stuck offsets g_i were computed with [N/m]
S_EV_T0 = 8  # running global slip: start time [s]
S_EV_X0 = 9  # running global slip: start position [m]
S_EV_PEAK = 10  # running global slip: sensor force at start [N]
S_EV_MIN = 11  # running global slip: lowest sensor force seen so far [N]
S_XS = 12  # stage position at S_T [m]
S_FN = 13  # input normal force at S_T [N]
S_STRIB = 14  # running global slip: Stribeck part of mu the elements can carry (kernel) [-]
S_EV_VMAX = 15  # running global slip: highest |V| seen so far [m/s]
N_FSTATE = 16

# --- integer state vector ---------------------------------------------------------------------
I_STAGE = 0  # 0 initial, 1 stable
I_GSLIP = 1  # 1 while a global slip runs
I_SIGN = 2  # direction of the running global slip (+1/-1)
I_NSLIP = 3  # completed global slips
I_KNOT = 4  # current knot index
I_OUT = 5  # next output sample index
I_NEVENT = 6  # number of events written to the event table
I_SLIPPED = 7  # a global slip ran since the last output sample (phase flag)
I_CHATTER = 8  # sample intervals where the event budget ran out (events skipped, see kernel)
I_FAST = 9  # output samples written by the fast stick recurrence (diagnostic)
I_TERM_ERR = 10  # 1 when a plug-in term gave a non-finite state (general path, RET_TERM_ERROR)
N_ISTATE = 11

# --- element weight table (float64, one row per kind, one column per element) ----------------
W_INITIAL = 0  # threshold share of each element in the initial stage, P_linear(i) m_i [-]
W_STABLE = 1  # threshold share of each element in the stable stage, P_uniform m_i [-]
W_UNIFORM = 2  # uniform load share 1/N (kinetic friction at re-stick) [-]
N_WROWS = 3
# (W_INITIAL and W_STABLE equal the stage numbers 0 and 1 of I_STAGE: row = stage)

# --- input knots (float64, one row per input, one column per knot) ---------------------------
K_T = 0  # knot time [s]
K_XS = 1  # stage position x_stage at the knot [m]
K_FN = 2  # input normal force at the knot [N]
N_KROWS = 3

# --- output tables (one row per channel, one column per output sample) -----------------------
# channel-major so that every channel is one contiguous array (SimResult takes views of the rows);
# one table per dtype, so that a sample costs what its values need (memory traffic of long runs)
O_FT = 0  # force-sensor output Ft [N]
O_FI = 1  # interface force F_interface [N]
O_X = 2  # specimen position X [m]
O_V = 3  # specimen velocity [m/s]
O_XS = 4  # stage position x_stage [m]
O_FN = 5  # effective normal force [N]
N_OROWS = 6  # rows of the float64 output table
F_STAGE = 0  # 0 initial, 1 stable
F_SLIP = 1  # 1 if a global slip ran since the previous sample, else 0
N_FROWS = 2  # rows of the uint8 flag table
# (the element modes, N per sample, are a third table, int8: elem[sample, element])

FN_CONTACT_MIN_N = 0.01
"""Below this normal force (half a force-sensor count) the specimens are treated as apart: the
interface carries no force and its elements restart unloaded when contact resumes."""

MAX_STEPS_PER_SAMPLE = 5000
"""Event budget per output interval. Chattering of thresholds near zero load can otherwise produce
events nanoseconds apart; past the budget the rest of the interval is integrated without events and
the interval is counted in I_CHATTER (reported in the result's metadata)."""

# --- event table columns ----------------------------------------------------------------------
E_T_START = 0
E_T_END = 1
E_PEAK = 2
E_TROUGH = 3
E_SLIP = 4
E_STAGE = 5
E_X_START = 6
E_FN = 7
E_V_PEAK = 8  # highest |V| of the slip [m/s]
N_ECOLS = 9

# --- kernel return codes ----------------------------------------------------------------------
RET_DONE = 0  # reached the end of the requested span
RET_SLIP_END = 1  # stopped right after a global slip ended (stop_on_slip_end was set)
RET_EVENT_TABLE_FULL = 2  # event table full: the caller grows it and calls again
RET_TERM_ERROR = 3  # a plug-in term made the state non-finite (general path); state left before it

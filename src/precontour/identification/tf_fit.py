"""Closed-loop transfer function x/X of one axis, identified from commanded and actual positions.

The servo loop reads the command only at its samples, so the map from the command samples X_k
to the encoder samples x_k is exactly a discrete-time linear system G_d(z) (friction aside): it
is identified in discrete time at the log's sample period, by output-error least squares
(Steiglitz-McBride iterations, then a Gauss-Newton polish with ``scipy.optimize.least_squares``)
on the tracking error e_k = X_k - x_k driven by the command increments dX_k = X_k - X_k-1:

    e = (1 - q^-1) b(q^-1) / a(q^-1) X = b(q^-1) / a(q^-1) dX,   x/X = 1 - (1 - q^-1) b / a,

which keeps x/X's static gain at exactly 1 (the loop has the plant's integrator) and keeps the
large absolute positions out of the regression. Unstable poles are reflected into the unit
disc. The continuous model that the closed-form predictor needs is G_c(s) = G_d(z) at
z = (1 + s T/2) / (1 - s T/2) (Tustin): the predictor drives G_c with the smooth spline
through the samples, so G_c(jw) must equal G_d(exp(jwT)) for the commands' frequencies w, and
Tustin does so up to the warping w' = (2/T) atan(wT/2) = w (1 - (wT)^2/12 + ...): the static
gain and the velocity and acceleration error constants are kept exactly and stability is
preserved. (Inverting the zero-order-hold equivalent instead would model a staircase input and
put the continuous model half a sample ahead: v T / 2 = 125 um at 250 mm/s, T = 1 ms.)
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy import optimize, signal

#: Orders tried by ``order="auto"``.
AUTO_ORDERS: tuple[int, ...] = (1, 2, 3, 4, 5, 6)
#: ``order="auto"`` takes the lowest order whose held-out error is within this factor of the
#: best, or within AUTO_ORDER_FLOOR_PCT (percentage points of max|e|) of it: smaller gains are
#: below what a log can tell apart.
AUTO_ORDER_SLACK = 1.25
AUTO_ORDER_FLOOR_PCT = 0.01
#: Fraction of an axis's active span (first to last commanded move) held out for validation.
HOLDOUT_FRACTION = 0.25
#: Samples within this time (s) after the command rests or reverses are left out of the cost:
#: there friction (stick-slip, the jump of the Coulomb torque) dominates, which no linear
#: model describes. Speeds below LOW_SPEED_FRACTION of the axis's top speed count as rest.
FRICTION_GUARD = 0.1
LOW_SPEED_FRACTION = 0.02
#: The guard also covers this many time constants of the loop's slowest pole (the friction
#: disturbance at a reversal decays with it: 0.8 s for pid-low's -6 rad/s), see
#: :func:`friction_guard_for`.
GUARD_TIME_CONSTANTS = 5.0
#: Steiglitz-McBride iterations (stops earlier when the denominator settles).
SM_ITERATIONS = 20
#: Largest pole radius of the discrete model; reflected poles are pulled inside it.
MAX_POLE_RADIUS = 0.9995


#: Fewest samples in the linear regime an axis needs to be identified.
MIN_FIT_SAMPLES = 200


class NotIdentifiable(ValueError):
    """The log does not determine this axis's model (the message says why, in one line)."""


@dataclass(frozen=True)
class DiscreteErrorModel:
    """e = b(q^-1)/a(q^-1) dX at sample period ``ts`` (a[0] = 1; b has len(a) - 1 terms)."""

    b: np.ndarray
    a: np.ndarray
    ts: float

    @property
    def order(self) -> int:
        return self.a.size - 1

    def closed_loop_z(self) -> tuple[np.ndarray, np.ndarray]:
        """x/X as (numerator, denominator) in powers of z, highest first (same length)."""
        g = self.a - np.convolve([1.0, -1.0], self.b)
        return g, self.a.copy()

    def simulate_error(self, dX: np.ndarray) -> np.ndarray:
        return signal.lfilter(self.b, self.a, dX)

    def continuous(self) -> tuple[np.ndarray, np.ndarray]:
        """x/X as a continuous transfer function (num, den in s, den monic) by inverse Tustin."""
        return tustin_to_continuous(*self.closed_loop_z(), self.ts)


def tustin_to_continuous(num_z: np.ndarray, den_z: np.ndarray, ts: float
                         ) -> tuple[np.ndarray, np.ndarray]:
    """G_c(s) = G_d((1 + s ts/2) / (1 - s ts/2)); coefficients highest power first.

    With n = deg den_z, P(z) (1 - s ts/2)^n = sum_i p_i (1 + s ts/2)^(n-i) (1 - s ts/2)^i.
    A pole of G_d at z = -1 (infinitely fast in s) lowers the degree of the result.
    """
    n = max(len(num_z), len(den_z)) - 1
    plus, minus = np.array([ts / 2, 1.0]), np.array([-ts / 2, 1.0])

    def substitute(p):
        p = np.concatenate([np.zeros(n + 1 - len(p)), p])
        out = np.zeros(n + 1)
        for i, coef in enumerate(p):
            term = np.polymul(_power(plus, n - i), _power(minus, i))
            out = np.polyadd(out, coef * term)
        return out

    num_s, den_s = substitute(np.asarray(num_z, float)), substitute(np.asarray(den_z, float))
    den_s = np.trim_zeros(den_s, "f")
    scale = den_s[0]
    num_s = np.trim_zeros(num_s, "f") / scale
    if num_s.size == 0:
        num_s = np.zeros(1)
    return num_s, den_s / scale


def _power(p: np.ndarray, k: int) -> np.ndarray:
    out = np.ones(1)
    for _ in range(k):
        out = np.polymul(out, p)
    return out


def stabilize(a: np.ndarray) -> np.ndarray:
    """Reflect roots of a(z) outside the unit circle (and pull in those on it)."""
    roots = np.roots(a)
    radius = np.abs(roots)
    if np.all(radius < MAX_POLE_RADIUS):
        return a
    outside = radius > 1.0
    roots = np.where(outside, 1.0 / np.conj(roots), roots)
    radius = np.abs(roots)
    roots = np.where(radius > MAX_POLE_RADIUS, roots * (MAX_POLE_RADIUS / radius), roots)
    return np.real(np.poly(roots)) * a[0]


def _regression(u: np.ndarray, y: np.ndarray, n: int) -> np.ndarray:
    """Rows [-y_k-1 .. -y_k-n, u_k .. u_k-n+1] for k = n .. N-1."""
    N = y.size
    cols = [-y[n - j:N - j] for j in range(1, n + 1)]
    cols += [u[n - j:N - j] for j in range(0, n)]
    return np.stack(cols, axis=1)


def steiglitz_mcbride(u: np.ndarray, y: np.ndarray, n: int, weights: np.ndarray
                      ) -> tuple[np.ndarray, np.ndarray]:
    """Output-error fit y = b/a u by Steiglitz-McBride on the samples where ``weights`` > 0."""
    a = np.ones(1)
    rows = np.flatnonzero(weights[n:] > 0)
    for _ in range(SM_ITERATIONS):
        uf = signal.lfilter([1.0], a, u)
        yf = signal.lfilter([1.0], a, y)
        phi = _regression(uf, yf, n)[rows]
        sol = np.linalg.lstsq(phi, yf[n:][rows], rcond=None)[0]
        a_new = stabilize(np.concatenate([[1.0], sol[:n]]))
        b = sol[n:]
        done = a.size == a_new.size and np.max(np.abs(a_new - a)) < 1e-8
        a = a_new
        if done:
            break
    return b, a


def output_error_refine(u: np.ndarray, y: np.ndarray, b: np.ndarray, a: np.ndarray,
                        weights: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Minimize sum w (y - b/a u)^2 from (b, a); returns the start if that is not bettered."""
    n = a.size - 1
    mask = weights > 0

    def residual(p):
        aa = np.concatenate([[1.0], p[:n]])
        if np.any(np.abs(np.roots(aa)) >= 1.0):
            return np.full(mask.sum(), 1e3 * (np.abs(y[mask]).max() + 1.0))
        return (signal.lfilter(p[n:], aa, u) - y)[mask]

    p0 = np.concatenate([a[1:], b])
    cost0 = np.sum(residual(p0) ** 2)
    try:
        sol = optimize.least_squares(residual, p0, method="trf", x_scale="jac", max_nfev=60 * (2 * n + 1))
    except (ValueError, np.linalg.LinAlgError):
        return b, a
    a1 = np.concatenate([[1.0], sol.x[:n]])
    if np.all(np.abs(np.roots(a1)) < MAX_POLE_RADIUS) and 2 * sol.cost < cost0:
        return sol.x[n:], a1
    return b, a


def fit_discrete(dX: np.ndarray, e: np.ndarray, order: int, ts: float, weights: np.ndarray,
                 *, refine: bool = True) -> DiscreteErrorModel:
    """Discrete error model of ``order`` from command increments and tracking errors."""
    su = np.std(dX[weights > 0]) or 1.0
    sy = np.std(e[weights > 0]) or 1.0
    b, a = steiglitz_mcbride(dX / su, e / sy, order, weights)
    if refine:
        b, a = output_error_refine(dX / su, e / sy, b, a, weights)
    return DiscreteErrorModel(b=b * (sy / su), a=a, ts=ts)


@dataclass(frozen=True)
class AxisIdentification:
    """The identified closed loop of one axis and how well it reproduces the log.

    ``num``, ``den``: continuous x/X (highest power first, ``den`` monic). Errors are in % of
    the measured max|e| of the part they are measured on: ``fit_pct`` on the whole log (final
    model, fitted on all of it), ``holdout_pct`` on the held-out last part of the axis's motion
    (model fitted without it). ``e_model`` is the identified model's tracking error over the
    log (discrete model, the log's own samples).
    """

    axis: str
    order: int
    num: np.ndarray
    den: np.ndarray
    discrete: DiscreteErrorModel
    fit_pct: float
    holdout_pct: float
    fit_rms_pct: float
    holdout_start: int
    e_model: np.ndarray
    orders_tried: dict


def _pct(err: np.ndarray, ref: np.ndarray) -> tuple[float, float]:
    scale = np.max(np.abs(ref))
    if scale == 0:
        return float("inf"), float("inf")
    return (float(100 * np.max(np.abs(err)) / scale),
            float(100 * np.sqrt(np.mean(err**2)) / np.sqrt(np.mean(ref**2))))


def active_span(X: np.ndarray) -> tuple[int, int] | None:
    """First and last sample index at which the command moves, or None if it never does."""
    moving = np.flatnonzero(np.diff(X) != 0)
    if moving.size == 0:
        return None
    return int(moving[0]), int(moving[-1]) + 2


def friction_guard_for(poles: np.ndarray) -> float:
    """Guard time (s) after rests and reversals for a loop with these (continuous) poles."""
    slowest = np.min(np.abs(np.asarray(poles).real))
    return float(max(FRICTION_GUARD, GUARD_TIME_CONSTANTS / slowest)) if slowest > 0 else FRICTION_GUARD


def linear_regime(X: np.ndarray, ts: float, guard: float = FRICTION_GUARD) -> np.ndarray:
    """1.0 where the command has moved one way at speed for at least ``guard`` s, else 0.0."""
    v = np.diff(X, prepend=X[0]) / ts
    vmax = np.max(np.abs(v))
    if guard <= 0 or vmax == 0:
        return np.ones(X.size)
    moving = np.where(np.abs(v) > LOW_SPEED_FRACTION * vmax, np.sign(v), 0.0)
    # A sample is "settled" if the sign of the speed has been the same nonzero value for the
    # last ``guard`` seconds: index of the last change of ``moving``, carried forward.
    change = np.flatnonzero(np.diff(moving, prepend=np.nan) != 0)
    last_change = np.zeros(X.size, dtype=int)
    last_change[change] = change
    last_change = np.maximum.accumulate(last_change)
    settled = (np.arange(X.size) - last_change >= int(round(guard / ts))) & (moving != 0)
    return settled.astype(float)


def identify_axis(axis: str, X: np.ndarray, x: np.ndarray, ts: float, *,
                  order: int | str = "auto", burn_in: int = 50,
                  friction_guard: float = FRICTION_GUARD) -> AxisIdentification:
    """Identify x/X of one axis from its command ``X`` and actual ``x`` sampled every ``ts``.

    The first ``burn_in`` samples, and the samples near rests and reversals of the command
    (:func:`linear_regime`), are left out of the cost; the fit percentages are measured on the
    same samples.
    """
    X = np.asarray(X, float)
    x = np.asarray(x, float)
    e = X - x
    dX = np.diff(X, prepend=X[0])
    span = active_span(X)
    if span is None:
        raise NotIdentifiable(f"axis {axis}: the command never moves in the log, so it cannot be "
                              "identified")
    first, last = span
    holdout_start = last - int(HOLDOUT_FRACTION * (last - first))
    weights = linear_regime(X, ts, friction_guard)
    weights[:burn_in] = 0.0
    estimation = weights.copy()
    estimation[holdout_start:] = 0.0
    if estimation.sum() < MIN_FIT_SAMPLES or weights[holdout_start:].sum() < MIN_FIT_SAMPLES // 4:
        raise NotIdentifiable(
            f"axis {axis}: only {int(weights.sum())} samples move steadily (away from rests and "
            f"reversals), too few to identify it; record a longer motion (precontour excite)")
    if not np.any(e[weights > 0]):
        raise NotIdentifiable(f"axis {axis}: the measured tracking error is exactly zero, so "
                              "there is no loop dynamics to identify")
    held = slice(holdout_start, last)

    orders = AUTO_ORDERS if order == "auto" else (int(order),)
    tried: dict[int, float] = {}
    candidates = {}
    for n in orders:
        # Orders are compared on Steiglitz-McBride fits; only the chosen one is polished.
        model = fit_discrete(dX, e, n, ts, estimation, refine=len(orders) == 1)
        err = model.simulate_error(dX) - e
        tried[n] = _pct(err[held][weights[held] > 0], e[held])[0]
        candidates[n] = model
    best = min(tried.values())
    chosen = min(n for n, v in tried.items()
                 if v <= max(AUTO_ORDER_SLACK * best, best + AUTO_ORDER_FLOOR_PCT))
    if len(orders) > 1:
        # The held-out score of the chosen order, polished like the final model.
        model = fit_discrete(dX, e, chosen, ts, estimation)
        tried[chosen] = _pct((model.simulate_error(dX) - e)[held][weights[held] > 0],
                             e[held])[0]
    final = fit_discrete(dX, e, chosen, ts, weights)
    e_model = final.simulate_error(dX)
    used = weights > 0
    fit_pct, fit_rms = _pct((e_model - e)[used], e[burn_in:])
    num, den = final.continuous()
    return AxisIdentification(axis=axis, order=chosen, num=num, den=den, discrete=final,
                              fit_pct=fit_pct, holdout_pct=tried[chosen], fit_rms_pct=fit_rms,
                              holdout_start=holdout_start, e_model=e_model, orders_tried=tried)

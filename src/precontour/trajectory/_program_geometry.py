"""Array geometry for the program planner (:mod:`.program`): how far a corner's blend
leaves its legs and its point (:func:`_across`, :func:`_segment_distance`,
:func:`_pose_distance`), how far the feed filters reach (:func:`_reach`) and the filters
themselves (:func:`_box`, moving averages by running sums), and the axis limits' ratios per
sample (:func:`_violations`). Vectorized over corners and samples."""

from __future__ import annotations

import numpy as np


def _across(v, w):
    """Per corner, the part of the velocity step ``w - v`` (rows: the legs' velocities, any
    dimension) that displaces its blend: the largest part across either leg (how far the
    blend leaves it) and across the corner's bisector (how far it passes from the corner
    point: for equal speeds the whole step, up to 1/cos(angle/2) times the part across a
    leg). Turning back by more than a right angle, the blend falls short of the corner point
    along the legs too (a full reversal: only along them): the whole step counts. A leg at
    rest (no direction) counts as turning back."""
    with np.errstate(divide="ignore", invalid="ignore"):
        d_v = v / np.linalg.norm(v, axis=1, keepdims=True)
        d_w = w / np.linalg.norm(w, axis=1, keepdims=True)
    d_v, d_w = np.nan_to_num(d_v), np.nan_to_num(d_w)
    step = w - v
    across = np.zeros(step.shape[0])
    bisector = d_v + d_w
    with np.errstate(divide="ignore", invalid="ignore"):
        bisector = np.nan_to_num(bisector / np.linalg.norm(bisector, axis=1, keepdims=True))
    for d in (d_v, d_w, bisector):
        along = np.einsum("ij,ij->i", step, d)[:, None] * d
        across = np.maximum(across, np.linalg.norm(step - along, axis=1))
    back = np.einsum("ij,ij->i", d_v, d_w) < 0.0
    back |= ~(d_v.any(axis=1) & d_w.any(axis=1))
    across[back] = np.linalg.norm(step[back], axis=1)
    return across


def _segment_distance(a, b):
    """Distance from the origin to the segments a + u b, u in [0, 1] (last axis: the
    coordinates)."""
    den = np.einsum("...k,...k->...", b, b)
    with np.errstate(divide="ignore", invalid="ignore"):
        u = np.clip(-np.einsum("...k,...k->...", a, b) / den, 0.0, 1.0)
    u[~(den > 0)] = 0.0
    return np.linalg.norm(a + u[..., None] * b, axis=-1)


def _pose_distance(a, b, c, d):
    """Over u in [0, 1], the least of max(|a + u b|, |c + u d|) (last axis: coordinates):
    how near a segment of poses (point a + u b, orientation c + u d, both over their
    tolerances) comes to the corner at the origin, both at once. Each norm is convex in u, so
    their maximum is least at one of their own minima, where they cross, or at an end."""
    def dot(x, y):
        return np.einsum("...k,...k->...", x, y)

    bb, ab, aa = dot(b, b), dot(a, b), dot(a, a)
    dd, cd, cc = dot(d, d), dot(c, d), dot(c, c)
    candidates = [np.zeros(aa.shape), np.ones(aa.shape)]
    with np.errstate(divide="ignore", invalid="ignore"):
        candidates.append(np.where(bb > 0, -ab / bb, 0.0))
        candidates.append(np.where(dd > 0, -cd / dd, 0.0))
        # |a + u b|^2 = |c + u d|^2: qa u^2 + 2 qb u + qc = 0
        qa, qb, qc = bb - dd, ab - cd, aa - cc
        root = np.sqrt(np.maximum(qb * qb - qa * qc, 0.0))
        linear = np.abs(qa) <= 1e-12 * np.maximum(bb, dd)
        candidates.append(np.where(linear, -0.5 * qc / qb, (-qb + root) / qa))
        candidates.append(np.where(linear, -0.5 * qc / qb, (-qb - root) / qa))
    best = np.full(aa.shape, np.inf)
    for u in candidates:
        u = np.clip(np.nan_to_num(u, nan=0.0, posinf=0.0, neginf=0.0), 0.0, 1.0)
        value = np.maximum(aa + u * (2.0 * ab + u * bb), cc + u * (2.0 * cd + u * dd))
        np.minimum(best, value, out=best)
    return np.sqrt(np.maximum(best, 0.0))


def _reach(n1, n2):
    """Integral of tau h(tau) over tau > 0, in samples, for the combined kernel h of moving
    averages of n1 and n2 samples (centred): how far a velocity step displaces a corner."""
    kernel = np.convolve(np.full(n1, 1.0 / n1), np.full(n2, 1.0 / n2))
    tau = np.arange(kernel.size) - 0.5 * (kernel.size - 1)
    return float(np.sum(np.where(tau > 0, tau * kernel, 0.0)))


def _box(x, n, pad):
    """Moving average of ``n`` samples along axis 1 of ``x`` (axes, samples) padded with
    ``pad`` copies of its first and last samples ('valid' part: x.shape[1] + 2 pad - n + 1
    samples)."""
    if pad:
        x = np.concatenate([np.repeat(x[:, :1], pad, axis=1), x,
                            np.repeat(x[:, -1:], pad, axis=1)], axis=1)
    if n == 1:
        return x
    # running sums relative to the first sample keep the round-off at the motion's own scale
    first = x[:, :1]
    c = np.zeros((x.shape[0], x.shape[1] + 1))
    np.cumsum(x - first, axis=1, out=c[:, 1:])
    return (c[:, n:] - c[:, :-n]) * (1.0 / n) + first


def _violations(q, ts, limits, orders=False):
    """Per sample of ``q`` (axes, samples), the largest ratio of an axis derivative (orders
    1-3, finite differences, at rest before and after) to its limit; and the overall worst.
    With ``orders``: the ratio and, per sample, the order of that derivative's stretch
    ratio^(1/order) which is the largest (what slowing down by a new clock must meet)."""
    ext = np.concatenate([np.repeat(q[:, :1], 3, axis=1), q, np.repeat(q[:, -1:], 3, axis=1)],
                         axis=1)
    n = q.shape[1]
    ratio = np.zeros(n)
    need = np.zeros(n)
    order_of = np.ones(n)
    d = ext
    for order in (1, 2, 3):
        d = np.diff(d, axis=1)
        scaled = np.abs(d) * (1.0 / (ts**order * limits[order - 1]))[:, None]
        r = np.maximum.reduce(scaled, axis=0)
        # difference i spans ext samples i..i+order, i.e. q samples i-3..i+order-3
        for shift in range(order + 1):
            first = 3 - shift           # difference feeding q sample 0
            lo, hi = max(0, -first), min(n, r.size - first)
            if hi > lo:
                part = r[lo + first:hi + first]
                np.maximum(ratio[lo:hi], part, out=ratio[lo:hi])
                if orders:
                    stretch = part ** (1.0 / order)
                    larger = stretch > need[lo:hi]
                    need[lo:hi][larger] = stretch[larger]
                    order_of[lo:hi][larger] = order
    if orders:
        # the ratio of the order that asks for the largest stretch
        return need ** order_of, order_of
    return ratio, float(ratio.max(initial=0.0))

"""AB3DMOT's footprint polygons in fixed-size arrays: Sutherland-Hodgman clipping, convex hulls and
their shoelace areas, with one float64 rounding per operation in the order of the rules below (a
polygon is ``x, y [..., W]`` with a count ``n [...]``; every function works elementwise over the
leading axes, e.g. all [N, K] detection-track pairs at once).

The rules (AB3DMOT 61f3bd7 ``dist_metrics.polygon_clip``; the hull as Andrew's monotone chain, the
area as a sequential shoelace sum, which give AB3DMOT's float32 values):

- clipping: the subject is clipped by each edge (a, b) of the convex counter-clockwise clip polygon
  in turn, from edge (last, first) on; a point p is inside iff
  ``(b.x - a.x)(p.y - a.y) > (b.y - a.y)(p.x - a.x)``; walking the subject's points e with their
  predecessors s (the last point first), an inside e after an outside s adds the crossing then e,
  an inside e after an inside s adds e, an outside e after an inside s adds the crossing; the
  crossing is ``(n1 dp - n2 dc) / (dc x dp)``, ``dc = a - b``, ``dp = s - e``, ``n1 = a x b``,
  ``n2 = s x e``. A stage that leaves no point makes the result empty (count 0). A convex
  quadrilateral clipped by another leaves at most ``CLIP_POINTS``; a stage beyond the buffer is
  reported (``overflow``);
- hull: points equal as floats counted once (the first kept), sorted by (x, y), the lower chain
  then the upper chain, each dropping its last point, a point popped while the turn
  ``(a - o) x (b - o) <= 0``;
- area: ``|sum_i x_i y_{i+1} - y_i x_{i+1}| / 2`` summed from the hull's first point on;
- degenerate (AB3DMOT's qhull raises there): a non-finite point, or a hull of fewer than 3 points.
"""

from __future__ import annotations

import jax.numpy as jnp
from jax import lax

from .exact import mul

__all__ = ["clip", "hull_area", "CLIP_POINTS"]

#: the most points a clip of two quadrilaterals can leave: a stage turns n points into at most
#: floor(1.5 n) (inside points plus two crossings per inside run), 4 -> 6 -> 9 -> 13 -> 19; in exact
#: arithmetic a convex clip leaves at most 8, but near-parallel edges (equal or turned boxes) make
#: AB3DMOT's float crossings leave more (9 seen), all of which its hull takes
CLIP_POINTS = 19


def _take(a, i):
    """a[..., i[...]] along the last axis (i of the leading shape, or with a last axis of its own)."""
    squeeze = i.ndim == a.ndim - 1
    out = jnp.take_along_axis(a, (i[..., None] if squeeze else i).astype(jnp.int32), axis=-1)
    return out[..., 0] if squeeze else out


def _inside(ax, ay, bx, by, px, py, zero):
    return mul(bx - ax, py - ay, zero) > mul(by - ay, px - ax, zero)


def _crossing(ax, ay, bx, by, sx, sy, ex, ey, zero):
    dcx, dcy = ax - bx, ay - by
    dpx, dpy = sx - ex, sy - ey
    n1 = mul(ax, by, zero) - mul(ay, bx, zero)
    n2 = mul(sx, ey, zero) - mul(sy, ex, zero)
    n3 = 1.0 / (mul(dcx, dpy, zero) - mul(dcy, dpx, zero))           # +-inf for parallel lines
    return (mul(mul(n1, dpx, zero) - mul(n2, dcx, zero), n3, zero),
            mul(mul(n1, dpy, zero) - mul(n2, dcy, zero), n3, zero))


def _stage(px, py, n, ax, ay, bx, by, zero):
    """One clip stage: points [..., W] (count n) against the edge (a, b) [...]. Returns the new
    points, count and whether more than W points came out."""
    w = px.shape[-1]
    k = jnp.arange(w)
    a = [v[..., None] for v in (ax, ay, bx, by)]
    valid = k < n[..., None]
    prev = jnp.clip(jnp.where(k == 0, n[..., None] - 1, k - 1), 0, w - 1)
    sx, sy = _take(px, prev), _take(py, prev)
    ins_e = _inside(*a, px, py, zero) & valid
    ins_s = _take(ins_e, prev) & valid
    cross = (ins_e != ins_s) & valid
    cnt = cross.astype(jnp.int32) + ins_e.astype(jnp.int32)
    incl = jnp.cumsum(cnt, axis=-1)
    start = incl - cnt
    cx, cy = _crossing(*a, sx, sy, px, py, zero)
    src = jnp.minimum(jnp.sum(incl[..., None, :] <= k[:, None], axis=-1), w - 1)   # output slot -> k
    use_cross = (_take(start, src) == k) & _take(cross, src)
    out_x = jnp.where(use_cross, _take(cx, src), _take(px, src))
    out_y = jnp.where(use_cross, _take(cy, src), _take(py, src))
    n_out = incl[..., -1]
    return out_x, out_y, jnp.where(n > 0, jnp.minimum(n_out, w), 0), n_out > w


def clip(sx, sy, cx, cy, zero, size: int = CLIP_POINTS):
    """The subject polygon (sx, sy [..., 4]) clipped by the convex counter-clockwise polygon
    (cx, cy [..., 4]), in buffers of ``size`` points: (x, y [..., size], count [...], overflow
    [...]: a stage left more than ``size`` points); count 0 where empty."""
    shape = jnp.broadcast_shapes(sx.shape, cx.shape)
    pad = jnp.zeros(shape[:-1] + (size - 4,), jnp.float64)
    px = jnp.concatenate([jnp.broadcast_to(sx, shape), pad], -1)
    py = jnp.concatenate([jnp.broadcast_to(sy, shape), pad], -1)
    cx, cy = jnp.broadcast_to(cx, shape), jnp.broadcast_to(cy, shape)

    def edge(e, carry):
        px, py, n, over = carry
        a = (e + 3) % 4
        ax, ay = _take(cx, jnp.full(shape[:-1], a)), _take(cy, jnp.full(shape[:-1], a))
        bx, by = _take(cx, jnp.full(shape[:-1], e)), _take(cy, jnp.full(shape[:-1], e))
        px, py, n, o = _stage(px, py, n, ax, ay, bx, by, zero)
        return px, py, n, over | o

    n = jnp.full(shape[:-1], 4, jnp.int32)
    return lax.fori_loop(0, 4, edge, (px, py, n, jnp.zeros(shape[:-1], bool)))


def _cross(ox, oy, ax, ay, bx, by, zero):
    return mul(ax - ox, by - oy, zero) - mul(ay - oy, bx - ox, zero)


def _chain(sx, sy, m, reverse: bool, zero):
    """The monotone chain over the sorted points (sx, sy [..., W], count m [...]), forwards or
    backwards: (stack x, y [..., W], its length). Each of the 2W steps pushes or pops."""
    w = sx.shape[-1]
    k = jnp.arange(w)

    def one(_, carry):
        hx, hy, size, i = carry
        active = i < m
        q = jnp.clip(m - 1 - i if reverse else i, 0, w - 1)
        qx, qy = _take(sx, q), _take(sy, q)
        top, sec = jnp.clip(size - 1, 0, w - 1), jnp.clip(size - 2, 0, w - 1)
        turn = _cross(_take(hx, sec), _take(hy, sec), _take(hx, top), _take(hy, top), qx, qy, zero)
        pop = active & (size >= 2) & (turn <= 0)
        push = active & ~pop
        at = push[..., None] & (k == size[..., None])
        hx, hy = jnp.where(at, qx[..., None], hx), jnp.where(at, qy[..., None], hy)
        return hx, hy, size - pop + push, i + push

    zeros = jnp.zeros(m.shape, jnp.int32)
    hx, hy, size, _ = lax.fori_loop(0, 2 * w, one, (jnp.zeros_like(sx), jnp.zeros_like(sy), zeros, zeros))
    return hx, hy, size


def _sorted_unique(px, py, n):
    """The points of (px, py [..., W], count n) counted once (the first of equal ones kept) and
    sorted by (x, y): (x, y [..., W], count)."""
    w = px.shape[-1]
    k = jnp.arange(w)
    valid = k < n[..., None]
    xj, yj, xk, yk = px[..., :, None], py[..., :, None], px[..., None, :], py[..., None, :]
    equal = (xj == xk) & (yj == yk)                                              # [..., j, k]
    before = (xj < xk) | ((xj == xk) & (yj < yk))
    dup = jnp.any(equal & valid[..., :, None] & (k[:, None] < k[None, :]), -2)
    uniq = valid & ~dup
    rank = jnp.where(uniq, jnp.sum(before & uniq[..., :, None], -2), w)
    src = jnp.argmax(rank[..., None, :] == k[:, None], -1)                       # [..., r] -> point
    return _take(px, src), _take(py, src), jnp.sum(uniq, -1)


def hull_area(px, py, n, zero):
    """Area of the convex hull of the points (px, py [..., W], count n): (area [...], degenerate
    [...]) by the module's rules; the area is 0 where degenerate."""
    w = px.shape[-1]
    k = jnp.arange(w)
    bad = jnp.any((k < n[..., None]) & ~(jnp.isfinite(px) & jnp.isfinite(py)), -1)
    sx, sy, m = _sorted_unique(px, py, n)
    lx, ly, n_low = _chain(sx, sy, m, False, zero)
    ux, uy, n_up = _chain(sx, sy, m, True, zero)
    cut = (n_low - 1)[..., None]
    many = (m > 2)[..., None]
    size = jnp.where(many[..., 0], n_low + n_up - 2, m)
    upper = many & (k >= cut)
    from_up = jnp.clip(k - cut, 0, w - 1)
    hx = jnp.where(upper, _take(ux, from_up), jnp.where(many, lx, sx))
    hy = jnp.where(upper, _take(uy, from_up), jnp.where(many, ly, sy))
    nxt = jnp.where(k + 1 < size[..., None], k + 1, 0)
    terms = mul(hx, _take(hy, nxt), zero) - mul(hy, _take(hx, nxt), zero)

    def add(i, acc):
        return jnp.where(i < size, acc + terms[..., i], acc)

    acc = lax.fori_loop(0, w, add, jnp.zeros(n.shape, jnp.float64))
    bad = bad | (size < 3)
    return jnp.where(bad, 0.0, jnp.abs(acc) * 0.5), bad

"""Edge scenes for ByteTrack's tracker: small frame lists (``[n, 5]`` float64 ``x1, y1, x2, y2,
score`` per frame) that reach the rules' corners, for JAX-vs-oracle tests."""

from __future__ import annotations

import numpy as np

__all__ = ["SCENES", "random_scene"]


def _f(*rows):
    return np.array(rows, dtype=np.float64).reshape(-1, 5)


def _moving(n, x0=100.0, dx=5.0, score=0.9, w=40.0, h=30.0, y0=100.0):
    return [_f([x0 + dx * t, y0, x0 + dx * t + w, y0 + h, score]) for t in range(n)]


def scenes() -> dict[str, list[np.ndarray]]:
    s = {}
    # scores exactly at the thresholds: 0.5 (neither high nor low), 0.6 (a birth), 0.1 (ignored)
    s["thresholds"] = [_f([10, 10, 50, 50, 0.6], [100, 10, 140, 50, 0.5], [200, 10, 240, 50, 0.1]),
                       _f([11, 10, 51, 50, 0.5], [101, 10, 141, 50, 0.6], [201, 10, 241, 50, 0.6]),
                       _f([12, 10, 52, 50, 0.1], [102, 10, 142, 50, 0.6], [202, 10, 242, 50, 0.6]),
                       _f([13, 10, 53, 50, 0.6000001], [103, 10, 143, 50, 0.5000001])]
    # equal IoUs: two identical detections per track, then two tracks on one detection
    s["equal_iou"] = [_f([10, 10, 50, 50, 0.9], [60, 10, 100, 50, 0.9]),
                      _f([35, 10, 75, 50, 0.9], [35, 10, 75, 50, 0.9]),
                      _f([35, 10, 75, 50, 0.9], [35, 10, 75, 50, 0.9]),
                      _f([35, 10, 75, 50, 0.9])] + [_f()] * 3 + [_f([35, 10, 75, 50, 0.8])] * 3
    # empty frames, a track lost past max_time_lost and found again at the edge
    s["empty_and_lost"] = _moving(4) + [_f()] * 12 + [_f([100 + 5 * 3, 100, 155, 130, 0.9])] * 3
    s["lost_edge"] = _moving(3) + [_f()] * 10 + [_f([110, 100, 150, 130, 0.9])] + [_f()] * 11 + \
        [_f([110, 100, 150, 130, 0.9])] * 2
    # boxes of zero width
    s["zero_width"] = [_f([10, 10, 10, 50, 0.9], [10, 10, 10, 50, 0.3])] * 4 + [_f([10, 10, 11, 50, 0.9])]
    # low detections keep a track; births below det_thresh
    s["low_keeps"] = _moving(3) + [_f([115, 100, 155, 130, 0.3])] * 3 + [_f([130, 100, 170, 130, 0.55])] * 2
    # duplicates between tracked and lost tracks
    s["duplicates"] = [_f([10, 10, 50, 50, 0.9])] * 3 + [_f([10, 10, 50, 50, 0.3], [12, 10, 52, 50, 0.9])] + \
        [_f([12, 10, 52, 50, 0.9])] * 2 + [_f([10, 10, 50, 50, 0.9], [12, 10, 52, 50, 0.9])] * 3
    # many objects: enough for a capacity overflow at a small capacity
    s["crowd"] = [_f(*[[20 * i, 10, 20 * i + 15, 40, 0.9] for i in range(12)])] * 3
    return s


SCENES = scenes()


def random_scene(seed: int, frames: int = 40, objects: int = 8) -> list[np.ndarray]:
    """Objects moving with jitter, detections dropped, duplicated, rounded to a coarse grid (ties)
    and scored around the thresholds."""
    rng = np.random.default_rng(seed)
    pos = rng.uniform(0, 300, (objects, 2))
    vel = rng.normal(0, 3, (objects, 2))
    size = rng.uniform(15, 60, (objects, 2))
    out = []
    for _ in range(frames):
        pos += vel
        rows = []
        for o in range(objects):
            if rng.random() < 0.2:
                continue
            x, y = np.round(pos[o] + rng.normal(0, 2, 2))
            w, h = np.round(size[o])
            sc = float(rng.choice([0.05, 0.1, 0.3, 0.5, 0.6, 0.65, 0.8, 0.95]))
            rows.append([x, y, x + w, y + h, sc])
            if rng.random() < 0.1:
                rows.append([x + 1, y, x + w + 1, y + h, sc])
        out.append(_f(*rows) if rows else _f())
    return out

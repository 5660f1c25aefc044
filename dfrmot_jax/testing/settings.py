"""Random settings across the sweep ranges and static options (tests and tooling)."""

from __future__ import annotations

import numpy as np

from ..trackers.dfr.config import CENTROIDS, FILTERS, KALMAN_INITS, MERGES, MODALITIES, OUTPUTS, Options, Params


def random_params(rng: np.random.Generator, output: str = "detections") -> Params:
    """Random settings; the weak detections' (added later) from a child of ``rng`` (``Generator.spawn``,
    which leaves ``rng``'s own stream as it was), so that every other draw is what it was before them."""
    weak = rng.spawn(1)[0]
    return Params(
        score_2d=float(rng.uniform(0.2, 0.8)), score_3d=float(rng.uniform(0.0, 8.0)),
        merge_iou=float(rng.uniform(0.1, 0.6)), a_c=float(rng.uniform(0.0, 0.3)), a_l=float(rng.uniform(2.0, 15.0)),
        alpha_c=float(rng.uniform(0.2, 0.8)), a_f=float(rng.uniform(-0.1, 0.3)), epsilon=int(rng.integers(0, 61)),
        gain_alpha=float(rng.uniform(0.3, 1.0)), gain_beta=float(rng.uniform(0.1, 1.0)),
        gain_gamma=float(rng.uniform(0.01, 0.3)), kf_q=float(np.exp(rng.uniform(np.log(0.01), np.log(100)))),
        kf_r=float(np.exp(rng.uniform(np.log(0.1), np.log(100)))), kf_p0=float(np.exp(rng.uniform(0, np.log(1000)))),
        keep_lost=int(rng.integers(0, 6)) if output == "filtered" else 0, min_hits=int(rng.integers(1, 4)),
        weak_2d=float(weak.uniform(0.0, 0.2)) if weak.integers(2) else 0.0,
        weak_3d=float(weak.uniform(0.0, 2.0)) if weak.integers(2) else 0.0, a_weak=float(weak.uniform(-0.1, 0.8)),
    )


def random_options(rng: np.random.Generator) -> Options:
    pick = lambda xs: xs[int(rng.integers(len(xs)))]  # noqa: E731
    return Options(filter=pick(FILTERS), merge=pick(MERGES), centroid=pick(CENTROIDS),
                   truncate=bool(rng.integers(2)), modality=pick(MODALITIES), output=pick(OUTPUTS),
                   kalman_init=pick(KALMAN_INITS))


def random_settings(rng: np.random.Generator, n: int) -> list[tuple[Params, Options]]:
    out = []
    for _ in range(n):
        o = random_options(rng)
        out.append((random_params(rng, o.output), o))
    return out

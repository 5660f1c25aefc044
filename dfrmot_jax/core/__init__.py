"""The tracker itself: jittable, pure functions. Imports only itself and the package's config.

Modules: ``boxes`` (the one IoU, the loaders' integer truncation, the predicted box), ``associate``
(fused affinity, greedy, Hungarian), ``filters`` (fixed gain, Kalman, steady state), ``memory``
(slots, births, ageing, overflow), ``step`` (``Frames``, ``StepOutput``, ``init``, ``step``), ``run``
(scan, vmap, sharding, the compiled-program cache), ``devices`` (one XLA device per core).
"""

from . import associate, boxes, devices, filters, memory, run, step

__all__ = ["associate", "boxes", "devices", "filters", "memory", "run", "step"]

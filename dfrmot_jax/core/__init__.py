"""The tracker itself: jittable, pure functions. Imports only itself, the package's config and the
platform it runs on (the package's ``devices``).

Modules: ``boxes`` (the one IoU, the loaders' integer truncation, the predicted box), ``associate``
(fused affinity, greedy, Hungarian), ``filters`` (fixed gain, Kalman, steady state), ``memory``
(slots, births, ageing, overflow), ``step`` (``Frames``, ``StepOutput``, ``init``, ``step``), ``run``
(scan, vmap, sharding, the compiled-program cache; the devices it runs on are the package's
``devices``').
"""

from . import associate, boxes, filters, memory, run, step

__all__ = ["associate", "boxes", "filters", "memory", "run", "step"]

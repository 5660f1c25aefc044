"""DFR-FastMOT (the authors' C++ code, reproduced exactly; the paper's variants as static options), the
first tracker family, in one folder. Its modules (imported where used, so that ``config`` reads no JAX):

- ``config``: ``Params`` (dynamic), ``Options`` (static), presets, validation, ``FAMILY_CONFIG``;
- ``frames``: a split's padded device inputs for the options (image box of a 3D detection, truncation);
- ``associate`` (fused affinity, greedy, Hungarian), ``filters`` (fixed gain, Kalman, steady state),
  ``memory`` (slots, births, ageing, overflow), ``step`` (``init``, ``step``), ``run`` (scan, vmap,
  sharding, the compiled-program cache);
- ``track``: the batch entry point (capacity from the data, overflow re-runs, compaction, distortions);
- ``results``: rows and result files; ``kalman_noise``: its Kalman noise fitted to the labels;
- ``family``: ``FAMILY``, the family as the protocol (:mod:`dfrmot_jax.trackers.protocol`) names it.
"""

__all__: list[str] = []

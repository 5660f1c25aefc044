"""What both metric families use (:mod:`dfrmot_jax.metrics.kitti2d`, :mod:`dfrmot_jax.metrics.ab3dmot`):
the place where they meet, importing neither.

Modules: ``box3d`` (the one rotated 3D / BEV box IoU), ``fields3d`` (the one set of rules for a
row's 3D fields), ``pairs`` (per-frame pair bookkeeping, segments and assignments).
"""

from . import box3d, fields3d, pairs

__all__ = ["box3d", "fields3d", "pairs"]

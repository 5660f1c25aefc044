"""What both metric families use (:mod:`dfrmot_jax.metrics.kitti2d`, :mod:`dfrmot_jax.metrics.samota`):
the one place where they meet, importing neither.

Modules: ``box3d`` (the one rotated 3D / BEV box IoU), ``fields3d`` (the one set of rules for a
row's 3D fields), ``pairs`` (per-frame pair bookkeeping, segments and assignments), ``distinct``
(distinct rows of float arrays, bit for bit), ``sequences`` (a class's sequence list, TrackEval's
KITTI class names, sequence names).
"""

from . import box3d, distinct, fields3d, pairs, sequences

__all__ = ["box3d", "distinct", "fields3d", "pairs", "sequences"]

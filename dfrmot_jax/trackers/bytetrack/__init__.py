"""ByteTrack (ifzhang/ByteTrack at d1bf019, ``yolox/tracker``), the camera-only tracker of the SORT line,
as the third tracker family (``family = "bytetrack"``), in pure JAX and exact to its code: the
reference runs' lines byte for byte, for many settings at once. Its modules (imported where used, so
that ``config`` reads no JAX):

- ``config``: ``Params`` (``track_thresh``, ``match_thresh``, ``track_buffer``, ``det_thresh_margin``;
  dynamic), ``Options`` (``fuse_score``, ``frame_rate``, ``demo_filter``, ``capacity``; static), the
  presets ``bytetrack_car`` / ``bytetrack_pedestrian`` (its defaults at KITTI's 10 frames/s), the one
  validator, ``FAMILY_CONFIG``;
- ``exact`` (float64 products kept apart from later sums), ``lapjv`` (``lap.lapjv`` with its cost limit,
  ties included, inside the scan), ``tracker`` (the 8-state Kalman filter per coordinate, the lists as
  codes with order keys, the two associations, births, removal, duplicates: ``init`` / ``step``),
  ``batch`` (``run``: a scan over frames vmapped over a ``Params`` batch), ``results`` (lines of the
  reference runs' format, the demo script's box filter);
- ``family``: ``FAMILY``, the family as the protocol (:mod:`dfrmot_jax.trackers.protocol`) names it.
"""

__all__: list[str] = []

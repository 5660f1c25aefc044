"""DFR-FastMOT as a tracker family (:class:`dfrmot_jax.trackers.protocol.TrackerFamily`), the first one: its
settings (:mod:`dfrmot_jax.trackers.dfr.config`), its tracker (:mod:`dfrmot_jax.trackers.dfr`: ``init`` / ``step`` over
padded frames, the compiled batch), its batch entry point (:func:`dfrmot_jax.trackers.dfr.track.track`, with the
capacity policy), its frames (:mod:`dfrmot_jax.data`), its rows and result files
(:mod:`dfrmot_jax.trackers.dfr.results`) and the checks of a config table that are DFR's own: filtered boxes of a
fixed-gain filter outside its stability region, ``keep_lost`` without filtered output. Nothing here
changes what any of them does; :data:`FAMILY` names them for the machinery
(:mod:`dfrmot_jax.trackers.registry`).
"""

from __future__ import annotations

import hashlib

import numpy as np
import pandas as pd

from ... import data, distort
from ...data import Split
from ...rows import lane_values
from ..protocol import TrackerFamily, class_columns
from . import results, run, step, track
from .config import FAMILY_CONFIG, MIN_CAPACITY, Options, Params, keep_thresholds
from .filters import fixed_gain_radius
from .frames import prepare_frames

__all__ = ["FAMILY", "compact_split", "lane_keys", "setting_problem", "output_slots", "table_problem", "unstable_gains",
           "unstable_message", "unstable_rows"]


def compact_split(split: Split, params: Params) -> Split:
    """The split without the detections no lane of ``params`` [B] keeps: compacted to the lanes'
    loosest score thresholds (:func:`dfrmot_jax.data.compact_split`; the same results)."""
    return data.compact_split(split, *(float(np.min(s)) for s in keep_thresholds(params)))


def output_slots(options: Options, per_lane: bool) -> tuple[int, int, bool]:
    """(track slots, bytes per slot, whether the slots are the options' own) of a lane's output:
    ``options.capacity``, or with capacity 0 (from the data) the fewest it can be
    (``config.MIN_CAPACITY``: a lower bound); 4 bytes of ids, + 16 of boxes when the lane has boxes of
    its own (output "filtered", or ``per_lane``: a distortion)."""
    return (options.capacity or MIN_CAPACITY, 4 + (16 if options.output == "filtered" or per_lane else 0),
            bool(options.capacity))


def unstable_gains(fixed, alpha, beta, gamma) -> np.ndarray:
    """[C] bool: lanes with the fixed-gain filter (``fixed`` [C] bool) and gains ([C] each) it is
    unstable with (spectral radius > 1, :func:`dfrmot_jax.trackers.dfr.filters.fixed_gain_radius`): their
    predicted and filtered boxes grow without bound. The one test sweeps, tunes and ``dfrmot track`` use."""
    return np.asarray(fixed, bool) & (fixed_gain_radius(alpha, beta, gamma) > 1.0 + 1e-9)


def unstable_message(what: str, alpha, beta, gamma, example: str = "", more: str = "") -> str:
    """Why ``what`` ("3 of 9 configs", "--class car") is refused: filtered boxes with unstable fixed gains."""
    return (f"{what} write filtered boxes with fixed gains outside the filter's stability region ({example}gain_alpha "
            f"{float(alpha):.4g}, gain_beta {float(beta):.4g}, gain_gamma {float(gamma):.4g}): their boxes grow "
            f"without bound; keep gain_gamma small against gain_beta (e.g. gamma <= beta / 4){more}")


def unstable_rows(table: pd.DataFrame) -> np.ndarray:
    """[C] bool: rows with the fixed-gain filter and gains it is unstable with (:func:`unstable_gains`;
    any class's gains)."""
    out = np.zeros(len(table), bool)
    fixed = (table["filter"] == "fixed_gain").to_numpy()
    for pre in [""] + sorted({c.split(".")[0] + "." for c in class_columns(table.columns, FAMILY_CONFIG) if "gain" in c}):
        cols = [pre + g if pre + g in table.columns else g for g in ("gain_alpha", "gain_beta", "gain_gamma")]
        out |= unstable_gains(fixed, *(table[c].to_numpy() for c in cols))
    return out


def table_problem(table: pd.DataFrame) -> tuple[str, str] | None:
    """(the sweep file's key, why) of the first configs of a config table DFR refuses, or None: filtered
    boxes with unstable fixed gains (:func:`unstable_rows`), ``keep_lost`` with output "detections"."""
    unstable = unstable_rows(table) & (table["output"] == "filtered").to_numpy()
    if unstable.any():
        r = table[unstable].iloc[0]
        return "params.gain_beta", unstable_message(
            f"{int(unstable.sum())} of {len(table)} configs", r["gain_alpha"], r["gain_beta"], r["gain_gamma"],
            f"e.g. config {int(r['config'])}: ", " or use [[variants]]")
    for kl in ["keep_lost"] + [c for c in class_columns(table.columns, FAMILY_CONFIG) if c.endswith(".keep_lost")]:
        bad = table[(table[kl] > 0) & (table["output"] == "detections")]
        if not len(bad):
            continue
        r = bad.iloc[0]
        return (f"params.{kl}", f"{kl} = {r[kl]} writes lost tracks' predicted boxes and needs output = \"filtered\" "
                                f"(variant {r['variant']!r} pairs it with output = \"detections\"); use [[variants]] "
                                f"to give keep_lost its own output")
    return None


def setting_problem(what: str, params: Params, options: Options) -> str | None:
    """Why one setting is refused (``TrackerFamily.setting_problem``): filtered boxes with unstable
    fixed gains (:func:`unstable_gains`); None when it runs."""
    p = params
    if options.output == "filtered" and unstable_gains([options.filter == "fixed_gain"], p.gain_alpha, p.gain_beta,
                                                       p.gain_gamma)[0]:
        return unstable_message(what, p.gain_alpha, p.gain_beta, p.gain_gamma, more=", or output=detections")
    return None


def lane_keys(res, base) -> list[bytes]:
    """One digest per lane of what its rows carry (``TrackerFamily.lane_keys``): the options, ``base``
    (the lane's digest of its ids and own image boxes) and, per row, the 3D source (``src3``,
    ``own3``); with output "filtered" also the lane's own 3D boxes. (With output "detections" a
    row's score and 3D box follow from the options, its slot and its 3D source, on the one split;
    with a distortion, the lane's levels and seed too.)"""
    ids = np.asarray(res.ids)
    rows = ids >= 0
    filtered = res.options.output == "filtered"
    src, own = np.asarray(res.src3), np.asarray(res.own3)
    out = []
    for b in range(ids.shape[0]):
        r = rows[b]
        h = hashlib.sha1(repr(res.options).encode())
        h.update(base[b])
        if res.distortion is not None:         # (its rows' scores and 3D boxes are the lane's own detections')
            h.update(res.distortion.key(b))
        h.update(src[b][r].astype(np.int32).tobytes())
        h.update(np.packbits(own[b][r]).tobytes())
        if filtered:
            h.update(np.ascontiguousarray(lane_values(res.box3, ids, b)).tobytes())
        out.append(h.digest())
    return out


#: DFR-FastMOT, the family ``"dfr"``
FAMILY = TrackerFamily(
    config=FAMILY_CONFIG, init=step.init, step=step.step, run_batch=run.run_batch, track=track.track,
    prepare_frames=prepare_frames, compact_split=compact_split, default_capacity=track.default_capacity,
    output_slots=output_slots, rows=results.kitti_rows, row_arrays=results.kitti_row_arrays,
    class_run=results.class_run, write_runs=results.write_runs, table_problem=table_problem,
    failing_rows=unstable_rows, setting_problem=setting_problem, lane_keys=lane_keys, box_format="g6",
    oracle="dfrmot_jax.testing.reference", distortion_spec=distort.make_spec)

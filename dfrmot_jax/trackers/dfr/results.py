"""From the tracker's padded output to rows and KITTI result files.

A lane's output is ``ids [T, K]`` (track id written in each output slot, -1 none) and, for its 3D
columns, ``src3 [T, K]`` (which 3D detection's values each row carries: the global flat index
``t * M3 + slot`` into the split's ``[T, M3]`` 3D arrays, -1 none; a stale box comes from an
earlier frame), ``own3 [T, K]`` (it is the object's own 3D detection, not the stale one of the
track it matched) and, with output "filtered", ``box3 [T, K, 6]`` (the track's filtered 3D
corners). The column sets themselves are in :mod:`dfrmot_jax.io.columns`.
"""

from __future__ import annotations

from pathlib import Path
from typing import NamedTuple

import numpy as np

from .config import Options
from ...distort import split_detections, split_detections_2d
from ...data import CLASS_NAMES, Split
from ...frames import Frames
from .frames import object_boxes, object_slots
from ...io.atomic import write_text_atomic
from ...io.columns import (COLUMN_SETS, PLACEHOLDER_DIMS, PLACEHOLDER_LOC, PLACEHOLDER_ROT_Y, PLACEHOLDER_SCORE,
                           as_written, invert_box3d_extent)
from ...io.result_writer import tracking_lines
from ...rows import KittiRows, RowSelection, padded_rows


class LaneRows(NamedTuple):
    """One lane's written lines for one sequence, in output order (frame, then slot).

    frame [R] int64 (within the sequence), track_id [R] int64, box [R, 4] float64,
    slot [R] int64 output slot (object slot with output "detections", track slot with "filtered").
    3D columns (None when not given): src3 [R] int64 global 3D index into the split's [T, M3]
    arrays (-1 none), own3 [R] bool, box3 [R, 6] float64 (filtered corners, NaN rows: none),
    score2 [R] float64 the written detection's own score (NaN: unknown).
    """

    frame: np.ndarray
    track_id: np.ndarray
    box: np.ndarray
    slot: np.ndarray
    src3: np.ndarray | None = None
    own3: np.ndarray | None = None
    box3: np.ndarray | None = None
    score2: np.ndarray | None = None


def output_boxes(frames: Frames, options: Options, boxes: np.ndarray | None = None) -> np.ndarray:
    """[T, K, 4] the written boxes: the objects' boxes (output "detections") or the lane's boxes."""
    if options.output == "detections":
        return object_boxes(frames, options)
    return boxes


def slot_scores(split: Split, frames: Frames, options: Options, score2=None, score3=None) -> np.ndarray | None:
    """[T, K] the detection score of each object slot (output "detections"; NaN for padding slots
    such as clutter), None for output "filtered" (slots are tracks).

    Object slots follow ``trackers.dfr.frames.object_boxes``: fused = the frames' 2D slots then their 3D slots;
    "2d" = 2D slots; "3d" = 3D slots. A 2D slot k < M2 is ``split.score2d[t, k]``, a 3D slot
    j < M3 ``split.score3d[t, j]``; ``score2`` / ``score3`` (with their frames' valid masks): other
    scores of the slots, a distorted lane's (:func:`lane_detections`).
    """
    if options.output != "detections":
        return None
    score2 = (split.score2d, split.valid2d) if score2 is None else score2
    score3 = (split.score3d, split.valid3d) if score3 is None else score3
    T = split.n_frames
    k2, k3 = frames.box2.shape[1], frames.box3.shape[1]

    def pad(a: np.ndarray, valid: np.ndarray, k: int) -> np.ndarray:
        out = np.full((T, k), np.nan)
        m = min(k, a.shape[1])
        out[:, :m] = np.where(valid[:, :m], a[:, :m], np.nan)
        return out

    return object_slots(options, pad(*score2, k2), pad(*score3, k3))


def lane_rows(split: Split, s: int, ids: np.ndarray, boxes: np.ndarray, *, src3: np.ndarray | None = None,
              own3: np.ndarray | None = None, box3: np.ndarray | None = None,
              scores: np.ndarray | None = None) -> LaneRows:
    """Rows of sequence s from one lane: ids [T, K], boxes [T, K, 4] (whole split).

    Optional [T, K] inputs give the rows' 3D columns: src3 (global 3D index, -1 none), own3
    (default: src3 >= 0), box3 [T, K, 6] (rows without src3 count as "no 3D filter"), scores
    (``slot_scores``).
    """
    sl = split.sequence_slice(s)
    ids_s = ids[sl]
    t, k = np.nonzero(ids_s >= 0)
    extra = {}
    if src3 is not None:
        src = np.asarray(src3)[sl][t, k].astype(np.int64)
        extra["src3"] = src
        extra["own3"] = (src >= 0) if own3 is None else np.asarray(own3)[sl][t, k].astype(bool) & (src >= 0)
    if box3 is not None:
        b3 = np.asarray(box3, np.float64)[sl][t, k]
        if src3 is not None:
            b3 = np.where((extra["src3"] >= 0)[:, None], b3, np.nan)
        extra["box3"] = b3
    if scores is not None:
        extra["score2"] = np.asarray(scores, np.float64)[sl][t, k]
    return LaneRows(t.astype(np.int64), ids_s[t, k].astype(np.int64), boxes[sl][t, k].astype(np.float64),
                    k.astype(np.int64), **extra)


def row_3d_values(split: Split, rows: LaneRows) -> dict:
    """Keyword arguments of ``io.columns.format_lines`` for the rows: has3, own3, dims, loc, rot_y,
    alpha, score3 (looked up in the split by ``rows.src3``), score2, box3."""
    out = {"score2": rows.score2, "box3": rows.box3}
    if rows.src3 is None:
        return out
    m3 = split.valid3d.shape[1]
    src = rows.src3
    size = split.valid3d.size
    if np.any((src < -1) | (src >= size)):
        raise ValueError(f"src3 out of range: expected -1 or 0..{size - 1} (t * M3 + slot, M3 = {m3})")
    has3 = src >= 0
    t, j = np.divmod(np.where(has3, src, 0), m3)
    if np.any(has3 & ~split.valid3d[t, j]):
        raise ValueError("src3 names an empty 3D detection slot")
    out.update(has3=has3, own3=rows.own3, dims=split.dims3d[t, j], loc=split.loc3d[t, j],
               rot_y=split.rot_y3d[t, j], alpha=split.alpha3d[t, j], score3=split.score3d[t, j])
    return out


class RowDetections(NamedTuple):
    """Per row [R]: the score of its object slot (``slot``: NaN without one, output "filtered") and
    the values of the 3D detection at its ``(tt, jj)`` (``score3``, ``rot_y``, ``dims`` [R, 3],
    ``loc`` [R, 3]), float64."""

    slot: np.ndarray
    score3: np.ndarray
    rot_y: np.ndarray
    dims: np.ndarray
    loc: np.ndarray


def lane_detections(split: Split, res, lane: np.ndarray, t: np.ndarray, k: np.ndarray, tt: np.ndarray,
                    jj: np.ndarray) -> RowDetections:
    """The detection values rows carry (:class:`RowDetections`): row r of lane ``lane[r]`` at frame
    ``t[r]``, object slot ``k[r]``, 3D detection ``(tt[r], jj[r])``. The split's values, or with a
    distortion (``res.distortion``, a ``distort.LaneDistortion``) each lane's own distorted
    detections (``LaneDistortion.lanes``: its scores, shifted centres, clutter boxes), read back one
    distinct distortion at a time."""
    frames, options = res.frames, res.options
    n = lane.size
    if res.distortion is None:
        slot = slot_scores(split, frames, options)
        at = (tt, jj)
        return RowDetections(np.full(n, np.nan) if slot is None else slot[t, k].astype(np.float64),
                             split.score3d[at], split.rot_y3d[at], split.dims3d[at], split.loc3d[at])
    out = RowDetections(np.full(n, np.nan), np.zeros(n), np.zeros(n), np.zeros((n, 3)), np.zeros((n, 3)))
    lanes, pos = np.unique(lane, return_inverse=True)
    pos = pos.reshape(-1)
    for d in res.distortion.lanes(split_detections(split), lanes, split_detections_2d(split)):
        r = np.isin(pos, d.which)
        at = (tt[r], jj[r])
        slot = slot_scores(split, frames, options, (d.dets2.score, d.dets2.valid), (d.dets.score, d.dets.valid))
        if slot is not None:
            out.slot[r] = slot[t[r], k[r]]
        out.score3[r], out.rot_y[r], out.dims[r], out.loc[r] = (d.dets.score[at], d.dets.rot_y[at], d.dets.dims[at],
                                                                  d.dets.loc[at])
    return out


def kitti_rows(split: Split, res, columns: str = "kitti", lanes=None) -> KittiRows:
    """The image box, score and 3D box each row of a ``track(detail=True)`` result carries in a
    ``--columns kitti`` (or ``kitti-stale``) result file, as flat arrays (:class:`KittiRows`): 3D
    metrics from the tracker's output without writing files. ``lanes``: only these lanes of ``res``
    (renumbered 0..len-1 in that order; default all).

    res: ids [B, T, K], -1 no row; boxes; src3 [B, T, K] global 3D index, -1 none; own3 [B, T, K];
    box3 [B, T, K, 6] with output "filtered"; frames; options. The rules are
    :func:`dfrmot_jax.io.columns.kitti_values`': a row carrying its own 3D detection (output
    "detections"; any 3D detection with "filtered") has that detection's rot_y and score; its box is
    the detection's (``h w l x y z``), or with "filtered" the track's filtered box written to 7
    significant digits as the file has it; every other row the placeholders ``-1 -1 -1 -1000 -1000
    -1000``, rot_y -10 and its 2D detection's score (1 unknown). ``columns="kitti-stale"``: a row
    carrying the matched track's stale 3D detection has its box and rot_y too (score still the 2D
    detection's). Every value equals what the written file reads back as (image boxes to 6
    significant digits, ``io.columns.fmt_g``).
    """
    frames, options = res.frames, res.options
    ids = np.asarray(res.ids)
    sel = RowSelection.of(ids, lanes)
    b, t, k, tk, rows_of = sel.lane, sel.t, sel.slot, sel.tk, sel.values
    src = rows_of(res.src3).astype(np.int64)
    has3 = src >= 0
    own = has3 if res.own3 is None else rows_of(res.own3).astype(bool) & has3
    filtered = options.output == "filtered"
    carry = has3 if filtered else own
    box_carry = has3 if columns == "kitti-stale" else carry
    m3 = split.valid3d.shape[1] if res.distortion is None else frames.valid3.shape[1]
    tt, jj = np.divmod(np.where(has3, src, 0), m3)
    n = b.size
    dets = lane_detections(split, res, sel.chosen[b], t, k, tt, jj)
    score = np.where(np.isfinite(dets.slot), dets.slot, PLACEHOLDER_SCORE)
    score[carry] = dets.score3[carry]
    rot_y = np.full(n, PLACEHOLDER_ROT_Y)
    rot_y[box_carry] = dets.rot_y[box_carry]
    dims = np.full((n, 3), PLACEHOLDER_DIMS)
    loc = np.full((n, 3), PLACEHOLDER_LOC)
    if filtered:
        rows3 = rows_of(res.box3).astype(np.float64)
        ok = has3 & np.all(np.isfinite(rows3), axis=1)
        d, l = invert_box3d_extent(rows3[ok, :3], rows3[ok, 3:], options.centroid)
        dims[ok], loc[ok] = as_written(d, 7), as_written(l, 7)
    else:
        dims[box_carry] = dets.dims[box_carry]
        loc[box_carry] = dets.loc[box_carry]
    if filtered or res.distortion is not None:
        # each lane's own boxes (a distortion's: its image boxes and 3D values, which another lane's
        # same slot or 3D index does not share), so no keys: the scorers tell the values apart by their bits
        box_key = box3d_key = None
        box = as_written(rows_of(res.boxes).astype(np.float64), 6)
    else:
        box_key = tk
        box3d_key = np.where(box_carry, src, -1)
        # the objects' boxes are every lane's: written once per object slot, then gathered
        box = as_written(np.asarray(output_boxes(frames, options), np.float64).reshape(-1, 4), 6)[box_key]
    box3d = np.concatenate([dims, loc, rot_y[:, None]], axis=1)
    return KittiRows(b, t, k, rows_of(ids).astype(np.int64), box, score, box3d, len(sel.chosen), ids.shape[1],
                     box_key, box3d_key)


def kitti_row_arrays(split: Split, res, columns: str = "kitti") -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """:func:`kitti_rows` as padded arrays (:func:`padded_rows`)."""
    return padded_rows(kitti_rows(split, res, columns), np.asarray(res.ids).shape)


def _check_columns(columns: str) -> None:
    if columns not in COLUMN_SETS:
        raise ValueError(f"columns={columns!r}: expected one of {COLUMN_SETS}")


class ClassRun(NamedTuple):
    """One class's lane to write: its split, prepared frames, options and outputs (``write_runs``)."""

    split: Split
    frames: Frames
    options: Options
    ids: np.ndarray
    boxes: np.ndarray | None = None
    src3: np.ndarray | None = None
    own3: np.ndarray | None = None
    box3: np.ndarray | None = None


def class_run(split: Split, res, lane: int = 0) -> ClassRun:
    """Lane ``lane`` of a ``track(detail=True)`` result on ``split`` as ``write_runs`` takes it."""
    return ClassRun(split, res.frames, res.options, res.ids[lane], res.lane_boxes(lane), res.src3[lane],
                    res.own3[lane], None if res.box3 is None else res.box3[lane])


def write_lane(out_dir, split: Split, frames: Frames, options: Options, ids: np.ndarray,
               boxes: np.ndarray | None = None, *, columns: str = "kitti", src3: np.ndarray | None = None,
               own3: np.ndarray | None = None, box3: np.ndarray | None = None) -> list[Path]:
    """Write one KITTI result file per sequence of the split for one lane (ids [T, K]).

    columns: "kitti" (standard KITTI results, default) | "authors" (the C++'s own 18 columns);
    see :mod:`dfrmot_jax.io.columns`. src3 [T, K] int (global 3D index ``t * M3 + slot`` of the
    3D detection each row carries, -1 none), own3 [T, K] bool (default src3 >= 0), box3 [T, K, 6]
    (output "filtered": the tracks' filtered 3D corners). Without src3 the 3D fields are
    placeholders; the kitti columns still carry each detection's own score (output "detections").
    """
    return write_runs(out_dir, [ClassRun(split, frames, options, ids, boxes, src3, own3, box3)], columns=columns)


def write_runs(out_dir, runs: list[ClassRun], *, columns: str = "kitti") -> list[Path]:
    """Write one result file per sequence of any run: several classes (one ``ClassRun`` each, e.g.
    car and pedestrian) share a sequence's file, merged frame by frame in the order of ``runs``,
    with each later class's track ids offset past the earlier classes' in that sequence so that
    ids are unique within a file. Returns the paths, sorted by sequence."""
    _check_columns(columns)
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    per_seq: dict[str, list[tuple[np.ndarray, list[str]]]] = {}
    next_id: dict[str, int] = {}
    for run in runs:
        split, options, ids = run.split, run.options, run.ids
        for name, a in (("src3", run.src3), ("own3", run.own3)):
            if a is not None and np.shape(a) != np.shape(ids):
                raise ValueError(f"write_lane: {name} has shape {np.shape(a)}, expected {np.shape(ids)} (as ids)")
        if run.box3 is not None and np.shape(run.box3) != np.shape(ids) + (6,):
            raise ValueError(f"write_lane: box3 has shape {np.shape(run.box3)}, expected {np.shape(ids) + (6,)}")
        allboxes = output_boxes(run.frames, options, run.boxes)
        scores = slot_scores(split, run.frames, options)
        for s, name in enumerate(split.names):
            r = lane_rows(split, s, ids, allboxes, src3=run.src3, own3=run.own3, box3=run.box3, scores=scores)
            v = row_3d_values(split, r)
            offset = next_id.get(name, 0)
            next_id[name] = offset + int(r.track_id.max(initial=-1)) + 1
            lines = tracking_lines(r.frame, r.track_id + offset, r.box, type_name=CLASS_NAMES[split.cls],
                                   alpha=v.get("alpha"), dims=v.get("dims"), loc=v.get("loc"), rot_y=v.get("rot_y"),
                                   score=v.get("score3"), columns=columns, centroid=options.centroid,
                                   has3=v.get("has3"), own3=v.get("own3"), score2=v.get("score2"), box3=v.get("box3"))
            per_seq.setdefault(name, []).append((r.frame, lines))
    paths = []
    for name in sorted(per_seq):
        frame = np.concatenate([f for f, _ in per_seq[name]])
        lines = [line for _, ls in per_seq[name] for line in ls]
        order = np.argsort(frame, kind="stable")
        path = out_dir / f"{name}.txt"
        write_text_atomic(path, "".join(lines[i] for i in order))
        paths.append(path)
    return paths

"""AB3DMOT as a tracker family (:class:`dfrmot_jax.trackers.protocol.TrackerFamily`), the family ``"ab3dmot"``:
its settings (:mod:`.config`), its tracker (:mod:`.tracker`, the compiled batch :mod:`.batch`), and
what the machinery around a tracker needs of it, on the splits every family reads
(:class:`dfrmot_jax.data.Split`; AB3DMOT reads its 3D detections only):

- :func:`prepare_frames`: a split's 3D detections as the tracker's ``Frames`` (with their image
  boxes, :class:`Prepared`);
- :func:`track`: a batch of settings over a split, in calls of ``lanes_per_call`` lanes, as a
  :class:`dfrmot_jax.trackers.protocol.TrackResult` whose track slots are in the order AB3DMOT writes its lines
  (newest track first): ``ids`` [B, T, K] (AB3DMOT's id counter, from 1 at the split's first
  frame), ``boxes`` the rows' image boxes (their last detection's), ``src3`` that detection's index
  ``t * M3 + slot``, ``box3`` [B, T, K, 7] the Kalman state ``x y z theta l w h``;
- :func:`rows`, :func:`write_runs`: the rows as AB3DMOT's result files carry them (``%f``) and the
  files, one per sequence, line for line those of AB3DMOT's ``save_results``.
"""

from __future__ import annotations

import hashlib
import warnings
from pathlib import Path
from typing import NamedTuple

import numpy as np

from ... import distort
from ..protocol import TrackResult
from ...data import CLASS_NAMES, Split
from .. import capacity
from ..lanes import calls_of_groups, widen
from ..protocol import TrackerFamily
from ...io.result_writer import write_class_files
from ...io.columns import as_written_fixed
from ...rows import KittiRows, padded_rows
from ...rows import Rows, RowSelection, lane_values, row_starts
from . import batch, tracker
from .config import FAMILY_CONFIG, Options, Params, validate
from .results import LINE_FORMAT

__all__ = ["FAMILY", "Prepared", "LanePrepared", "Ab3dmotRun", "prepared", "distortion_spec", "distorted_lanes",
           "lane_prepared", "prepare_frames", "track", "rows", "row_arrays", "class_run",
           "write_runs", "default_capacity", "setting_problem", "lane_calls", "stacked_frames",
           "output_slots", "lane_keys",
           "BYTES_PER_SLOT"]

#: a lane's output bytes per track slot and frame: ids, the detection index (int32 each), the image
#: box (4 float64), the 3D box (7 float64), whether a row (bool)
BYTES_PER_SLOT = 4 + 4 + 32 + 56 + 1


class Prepared(NamedTuple):
    """A split's detections as AB3DMOT's tracker takes them: ``frames`` (:class:`.tracker.Frames`
    [T, M3, ...], the 3D detections in file order, padding zeroed), ``image`` [T, M3, 4] their
    image boxes (the 3D detector's own ``x1 y1 x2 y2``) and ``alpha`` [T, M3] their observation
    angles (what a result line carries beside the tracker's state; None: the split's)."""

    frames: tracker.Frames
    image: np.ndarray
    alpha: np.ndarray | None = None

    def detections(self) -> distort.Detections3D:
        """The detections as ``distort`` reads them (float64 file values)."""
        b = self.frames.boxes
        alpha = np.zeros(b.shape[:2]) if self.alpha is None else self.alpha
        return distort.Detections3D(np.asarray(self.frames.valid, bool), self.frames.score, b[..., :3], b[..., 3],
                                    b[..., [6, 5, 4]], alpha, self.image)


class LanePrepared(NamedTuple):
    """Each lane's :class:`Prepared` frames where lanes track different detections (a distortion
    study): ``preps`` the distinct ones, ``of`` [B] each lane's; a ``TrackResult``'s ``frames``."""

    preps: tuple
    of: np.ndarray


def prepared(dets: distort.Detections3D, reset) -> Prepared:
    """3D detections (file values, float64) as the tracker's frames: boxes ``x y z th l w h``."""
    valid = np.asarray(dets.valid, bool)
    boxes = np.concatenate([dets.loc, dets.rot_y[..., None], dets.dims[..., ::-1]], axis=-1)      # x y z th l w h
    boxes = np.where(valid[..., None], boxes, 0.0).astype(np.float64)
    score = np.where(valid, dets.score, 0.0).astype(np.float64)
    return Prepared(tracker.Frames(boxes, valid, score, np.asarray(reset, bool)), np.asarray(dets.image, np.float64),
                    np.asarray(dets.alpha, np.float64))


def prepare_frames(split: Split, options: Options | None = None) -> Prepared:
    """``split``'s 3D detections as the tracker's frames (the same for every ``Options``)."""
    return prepared(distort.split_detections(split), split.reset)


def distortion_spec(options=None, clutter_slots: int = 0, burst_max: int = 30, burst_dist: str = "fixed",
                    frames: Prepared | None = None, dps=None, **kw) -> distort.DistortSpec:
    """The ``DistortSpec`` of AB3DMOT's lanes (``TrackerFamily.distortion_spec``; ``options``, its
    own, change nothing): image boxes as the detector wrote them (no truncation), the 3D shift in
    ``DistortSpec.centroid``'s axes (DFR-FastMOT's default, ``"legacy"``: the same physical shift as
    its runs with that convention), the clutter's laws measured on ``frames``' 3D detections as
    DFR-FastMOT measures them on its own (the same values); only the groups of ``dps``' 3D levels."""
    f3 = None
    if frames is not None:
        f3 = distort.frames_3d(frames.detections(), frames.frames.reset, kw.get("centroid", "legacy"))
    return distort.make_spec(None, clutter_slots=clutter_slots, burst_max=burst_max, burst_dist=burst_dist, frames=f3,
                             dps=None if dps is None else distort.only_3d(dps), **{"truncate": False, **kw})


def distorted_lanes(split: Split, prep: Prepared, dps, spec: distort.DistortSpec) -> tuple[LanePrepared,
                                                                                           distort.LaneDistortion]:
    """Each lane's distorted detections (``dps`` leaves [B]): the distinct distortions' frames
    (:meth:`distort.LaneDistortion.lanes` on the 3D detections alone, :func:`distort.distortion_3d`;
    2D levels ignored), each frame's detections left packed to its first slots in their order (as
    AB3DMOT reads a detection file: its tracker takes a frame's valid slots as a prefix), the clutter
    after the real ones; a lane whose levels are all 0 the undistorted ``prep`` itself."""
    lanes = distort.distortion_3d(split, prep.detections(), dps, spec)
    b = len(np.asarray(dps.seed))
    of = np.zeros(b, np.int64)
    preps = []
    for d in lanes.lanes(prep.detections(), np.arange(b)):
        of[d.which] = len(preps)
        zero = distort.is_zero(distort.lane_params(lanes.params, int(d.which[0])))
        preps.append(prep if zero else prepared(d.dets.packed(), prep.frames.reset))
    return LanePrepared(tuple(preps), of), lanes


def default_capacity(frames: Prepared, params: Params, options: Options, clutter_slots: int = 0) -> int:
    """Track slots from the data (:func:`.batch.data_capacity`; ``clutter_slots`` more)."""
    return min(capacity.MAX_CAPACITY, batch.data_capacity(frames.frames) + 4 * int(clutter_slots))


def output_slots(options: Options, per_lane: bool) -> tuple[int, int, bool]:
    """(track slots, bytes per slot, whether the slots are the options' own) of a lane's output:
    ``options.capacity``, or with capacity 0 (from the data) 16, a lower bound."""
    return options.capacity or 16, BYTES_PER_SLOT, bool(options.capacity)


def compact_split(split: Split, params: Params) -> Split:
    """``split`` as it is: every detection is tracked whatever the settings (``score_threshold``
    selects written lines only)."""
    return split


def stacked_frames(preps) -> tracker.Frames:
    """The frames of several :class:`Prepared` of one shape, stacked on a lane axis: boxes
    [T, D, N, 7], valid and score [T, D, N], reset [T] (the first's; the same split)."""
    fr = [q.frames for q in preps]
    return tracker.Frames(np.stack([f.boxes for f in fr], 1), np.stack([f.valid for f in fr], 1),
                          np.stack([f.score for f in fr], 1), fr[0].reset)


def lane_calls(frames: LanePrepared, params: Params, per: int) -> list[tuple]:
    """The compiled calls of a distortion study's lanes (``params`` leaves [B], ``frames.of`` [B]
    each lane's distinct frames): lanes whose frames have one shape share calls, each call holding
    at most ``per`` tracking lanes (:func:`dfrmot_jax.trackers.lanes.calls_of_groups`; lanes on different frames never track
    alike). Per call: (its lanes [L] (indices into B), the distinct frames it reads [D'] (indices
    into ``frames.preps``), each lane's among them [L], its number of tracking lanes)."""
    shapes = [np.shape(q.frames.valid) for q in frames.preps]
    out = []
    for shape in dict.fromkeys(shapes):
        ds = np.flatnonzero([s == shape for s in shapes])
        group = np.flatnonzero(np.isin(frames.of, ds))
        sub = Params(*(np.asarray(v)[group] for v in params))
        of = frames.of[group]
        tracks = batch.tracking_lanes(sub, of)[1]
        for at in calls_of_groups(tracks, per):
            used, local = np.unique(of[at], return_inverse=True)
            out.append((group[at], used, local.reshape(-1), len(np.unique(tracks[at]))))
    return out


def _run_calls(prep: Prepared, frames: LanePrepared | None, p: Params, options: Options, per: int, grow: bool,
               rows_only: bool) -> tuple[list, list, list, dict, dict]:
    """:func:`track`'s compiled calls: every lane of ``p`` (leaves [B]) on ``prep`` (or, with a
    distortion, on its own of ``frames``): (each call's lanes, its ``RunOutput``, its image boxes
    [L, T, K, 4] (without ``rows_only``), and with ``rows_only`` per lane its image and 3D boxes at
    its rows only (in (frame, slot) order, newest slot first: ``Rows``' values), not dense)."""
    calls, outs, image, rows3, rows2 = [], [], [], {}, {}

    def keep(at, out: batch.RunOutput, image_of) -> None:
        """A call's output for lanes ``at``; ``image_of(j, src)``: the image boxes of its lane j's
        detections ``src``."""
        calls.append(at)
        if rows_only:
            live = out.ids[:, :, ::-1] >= 0
            for j, lane in enumerate(at):
                rows3[lane] = out.boxes[j][:, ::-1][live[j]]
                rows2[lane] = image_of(j, out.src[j][:, ::-1][live[j]])
            out = out._replace(boxes=None)
        else:
            image.append(np.stack([image_of(j, np.maximum(out.src[j], 0)) for j in range(len(at))]))
        outs.append(out)

    if frames is None:
        flat = prep.image.reshape(-1, 4)
        for at in calls_of_groups(batch.tracking_lanes(p)[1], per):
            keep(at, batch.run(Params(*(v[at] for v in p)), prep.frames, options, grow=grow),
                 lambda j, src: flat[src])
    else:       # the lanes of every distinct distortion in shared calls, each on its own frames
        todo = lane_calls(frames, p, per)
        # every call padded to the most tracking lanes any call holds (<= per): one compilation, no more work
        most = max(n for *_, n in todo)
        for at, used, local, _ in todo:
            qs = [frames.preps[d] for d in used]
            out = batch.run(Params(*(v[at] for v in p)), stacked_frames(qs), options, grow=grow, frame_of=local,
                            lanes=most)
            flats = [q.image.reshape(-1, 4) for q in qs]
            keep(at, out, lambda j, src, flats=flats, local=local: flats[local[j]][src])
    return calls, outs, image, rows2, rows3


def track(split: Split | Prepared, params: Params, options: Options = Options(), *, lanes_per_call: int | None = None,
          grow: bool = True, detail: bool = True, rows_only: bool = False, distortion=None, spec=None,
          clutter_slots: int = 0) -> TrackResult:
    """Every lane of ``params`` (scalars: one lane; leaves [B]) over ``split`` (or its
    :class:`Prepared` frames): a :class:`dfrmot_jax.trackers.protocol.TrackResult` (see the module's docstring;
    ``own3`` marks the rows, ``capacity`` [B] the slots each lane ran with). ``lanes_per_call``:
    tracking lanes per compiled call (default all; lanes that track alike share one,
    :func:`dfrmot_jax.trackers.lanes.calls_of_groups`); ``grow``: a call whose lanes run out of track slots runs again with twice
    as many (:func:`.batch.run`); ``rows_only``: ``boxes`` and ``box3`` as
    :class:`dfrmot_jax.rows.Rows`. ``detail`` is always on (the rows' detections come with the ids).
    A lane where AB3DMOT's own run would have stopped (degenerate geometry) or whose greedy sort
    AB3DMOT breaks differently is named in a warning.

    ``distortion``: ``distort.DistortParams`` (scalars or leaves [B]; needs the ``Split``, whose
    labels give the bursts' identities): lane b tracks its 3D detections distorted by its own levels
    and seed, the draws DFR-FastMOT's lanes take (:func:`distorted_lanes`; 2D levels change nothing
    here), on its distortion's materialised frames, the lanes of all distortions batched into shared
    calls (:func:`lane_calls`, each lane on its own frames, :func:`.batch.run`'s ``frame_of``);
    ``spec`` / ``clutter_slots``: the static ``DistortSpec`` (default :func:`distortion_spec` of the
    data and the levels). The result's ``frames`` are then a :class:`LanePrepared` and its
    ``distortion`` the ``distort.LaneDistortion``; its rows carry each lane's distorted detections."""
    validate(params, options)
    if not options.boxes:
        raise ValueError(f"AB3DMOT: {BOXES_PROBLEM}")
    prep = split if isinstance(split, Prepared) else prepare_frames(split, options)
    p = batch.broadcast_lanes(params)
    b = len(p.threshold)
    per = max(1, int(lanes_per_call or b))
    frames, lanes = prep, None
    if distortion is not None:
        if not isinstance(split, Split):
            raise ValueError("track(distortion=...) needs the Split (its ground truth), not prepared frames")
        dps = distort.DistortParams(*(np.broadcast_to(np.asarray(v), (b,)) for v in distortion))
        if spec is None:
            spec = distortion_spec(clutter_slots=clutter_slots, frames=prep, dps=dps)
        distort.check_params(distort.only_3d(dps), spec)
        frames, lanes = distorted_lanes(split, prep, dps, spec)
    calls, outs, image, rows2, rows3 = _run_calls(prep, frames if distortion is not None else None, p, options, per,
                                                  grow, rows_only)
    back = np.argsort(np.concatenate(calls), kind="stable")     # (each lane's place among the calls' lanes)
    k = max(o.ids.shape[2] for o in outs)
    ids = np.concatenate([widen(o.ids, k, -1) for o in outs])[back][:, :, ::-1]
    src = np.concatenate([widen(o.src, k, -1) for o in outs])[back][:, :, ::-1]
    ids = np.ascontiguousarray(ids, np.int32)
    src = np.where(ids >= 0, src, -1).astype(np.int32)
    if rows_only:           # (the rows of every lane in lane order: ``Rows.of`` of the dense arrays)
        start, t = row_starts(ids), ids.shape[1]
        boxes = Rows(np.concatenate([rows2[lane] for lane in range(b)]), start, t)
        box3_out = Rows(np.concatenate([rows3[lane] for lane in range(b)]), start, t)
    else:
        box3_out = np.ascontiguousarray(np.concatenate([widen(o.boxes, k, 0.0) for o in outs])[back][:, :, ::-1])
        boxes = np.ascontiguousarray(np.concatenate([widen(v, k, 0.0) for v in image])[back][:, :, ::-1])
        boxes[ids < 0] = np.nan
    counters = {n: np.concatenate([getattr(o, n) for o in outs])[back] for n in ("dropped", "overflow", "peak",
                                                                                "degenerate", "fallback")}
    bad = np.flatnonzero((counters["degenerate"] > 0) | (counters["fallback"] > 0))
    if bad.size:
        warnings.warn(f"AB3DMOT: lanes {bad[:8].tolist()} met a pair whose geometry AB3DMOT cannot compute or a "
                      f"greedy tie its sort breaks differently: their tracks are this package's, not AB3DMOT's",
                      UserWarning, stacklevel=2)
    capacity = np.concatenate([np.asarray(o.capacity, np.int64) for o in outs])[back]     # (batch.run sets it)
    ran = outs[-1].options._replace(capacity=int(capacity.max(initial=0)))
    return TrackResult(ids, boxes, counters["dropped"].astype(np.int32), counters["overflow"].astype(np.int32),
                       counters["peak"].astype(np.int32), src, ids >= 0, box3_out, capacity, frames, ran, lanes)


def lane_prepared(res: TrackResult, lanes) -> list[tuple[np.ndarray, Prepared]]:
    """The frames ``lanes`` (lane indices of ``res``) tracked: (the positions in ``lanes`` of each
    distinct :class:`Prepared`, it)."""
    lanes = np.asarray(lanes, np.int64)
    frames = res.frames
    if not isinstance(frames, LanePrepared):
        return [(np.arange(lanes.size), frames)]
    of = frames.of[lanes]
    return [(np.flatnonzero(of == d), q) for d, q in enumerate(frames.preps) if np.any(of == d)]


def rows(split: Split, res: TrackResult, columns: str = "kitti", lanes=None) -> KittiRows:
    """The rows of ``res``' lanes (``lanes``: only these, renumbered 0..len-1; default all) as
    AB3DMOT's result files carry them (:class:`dfrmot_jax.rows.KittiRows`): the last matched
    detection's image box and score, the Kalman state's 3D box ``h w l x y z rot_y``, every value
    as ``%f`` reads back. ``columns`` ("kitti" or "kitti-stale") changes nothing: each row carries
    its own 3D box."""
    ids = np.asarray(res.ids)
    sel = RowSelection.of(ids, lanes)
    rows_of = sel.values
    src = rows_of(res.src3).astype(np.int64)
    box, score = np.zeros((src.size, 4)), np.zeros(src.size)
    for at, q in lane_prepared(res, sel.chosen):       # (each lane's own detections: a distortion's)
        r = np.isin(sel.lane, at)
        box[r] = q.image.reshape(-1, 4)[src[r]]
        score[r] = q.frames.score.reshape(-1)[src[r]]
    box, score = as_written_fixed(box), as_written_fixed(score)
    state = rows_of(res.box3).astype(np.float64)
    box3d = as_written_fixed(state[:, [6, 5, 4, 0, 1, 2, 3]])
    return KittiRows(sel.lane, sel.t, sel.slot, rows_of(ids).astype(np.int64), box, score, box3d, len(sel.chosen),
                     ids.shape[1])


def row_arrays(split: Split, res: TrackResult, columns: str = "kitti") -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """:func:`rows` as padded arrays (:func:`dfrmot_jax.rows.padded_rows`)."""
    return padded_rows(rows(split, res, columns), np.asarray(res.ids).shape)


class Ab3dmotRun(NamedTuple):
    """One class's lane to write (:func:`write_runs`): its split, ids [T, K], the rows' detections
    src3 [T, K] and 3D boxes box3 [T, K, 7] (the Kalman state), slots in writing order; ``prep``
    the detections it tracked (their image boxes, scores and angles; None: the split's)."""

    split: Split
    ids: np.ndarray
    src3: np.ndarray
    box3: np.ndarray
    prep: Prepared | None = None


def class_run(split: Split, res: TrackResult, lane: int = 0) -> Ab3dmotRun:
    """Lane ``lane`` of a :func:`track` result on ``split`` as :func:`write_runs` takes it."""
    ids = np.asarray(res.ids)
    box3 = res.box3.lane_dense(lane, ids[lane], 0.0) if isinstance(res.box3, Rows) else np.asarray(res.box3)[lane]
    return Ab3dmotRun(split, ids[lane], np.asarray(res.src3)[lane], box3, lane_prepared(res, [lane])[0][1])


def _sequence_lines(run: Ab3dmotRun, s: int, offset: int) -> tuple[list[str], int]:
    """Sequence ``s`` of a run as AB3DMOT's lines (ids + ``offset``), and its largest id written."""
    split = run.split
    sl = split.sequence_slice(s)
    ids = np.asarray(run.ids)[sl]
    t, k = np.nonzero(ids >= 0)
    src = np.asarray(run.src3)[sl][t, k].astype(np.int64)
    q = run.prep
    image = q.image.reshape(-1, 4)[src]
    alpha = np.asarray(split.alpha3d if q.alpha is None else q.alpha, np.float64).reshape(-1)[src]
    score = q.frames.score.reshape(-1)[src]
    x, y, z, th, l, w, h = np.asarray(run.box3, np.float64)[sl][t, k].T
    name = CLASS_NAMES[split.cls]
    frame = np.asarray(split.frame)[sl][t]
    tid = ids[t, k].astype(np.int64) + offset
    lines = [LINE_FORMAT % (frame[i], tid[i], name, alpha[i], *image[i], h[i], w[i], l[i], x[i], y[i], z[i], th[i],
                            score[i]) for i in range(len(t))]
    return lines, int(tid.max(initial=offset))


def write_runs(out_dir, runs: list[Ab3dmotRun], *, columns: str = "kitti") -> list[Path]:
    """One result file per sequence of any run, AB3DMOT's lines (``frame id type 0 0 alpha x1 y1 x2
    y2 h w l x y z rot_y score``, ``%f``; a frame's newest track first). Several classes (one run
    each) share a sequence's file, frame by frame in the order of ``runs``, each later class's ids
    offset past the largest id written before it in that sequence. ``columns``: "kitti" (the only
    layout AB3DMOT writes; "kitti-stale" is the same). Returns the paths, sorted by sequence."""
    if columns not in ("kitti", "kitti-stale"):
        raise ValueError(f"columns={columns!r}: AB3DMOT writes its own KITTI lines only (kitti)")
    per_seq: dict[str, list[tuple[np.ndarray, list[str]]]] = {}
    top: dict[str, int] = {}
    for run in runs:
        if run.prep is None:        # (the split's own detections, prepared once per run)
            run = run._replace(prep=prepare_frames(run.split))
        for s, name in enumerate(run.split.names):
            lines, most = _sequence_lines(run, s, top.get(name, 0) if name in per_seq else 0)
            frames = np.array([int(line.split(" ", 1)[0]) for line in lines], np.int64)
            per_seq.setdefault(name, []).append((frames, lines))
            top[name] = max(top.get(name, 0), most)
    return write_class_files(out_dir, per_seq)


BOXES_PROBLEM = "boxes = false writes no 3D boxes, which the result rows carry; keep boxes = true"


def table_problem(table) -> tuple[str, str] | None:
    """(``options.boxes``, why) when a config has ``boxes = false`` (its rows would have no 3D boxes:
    refused before anything is written), else None: AB3DMOT runs every other valid setting."""
    if "boxes" in table.columns and not table["boxes"].astype(bool).all():
        r = table[~table["boxes"].astype(bool)].iloc[0]
        return "options.boxes", (f"{int((~table['boxes'].astype(bool)).sum())} of {len(table)} configs (e.g. config "
                                 f"{int(r['config']) if 'config' in table.columns else r.name}): {BOXES_PROBLEM}")
    return None


def failing_rows(table) -> np.ndarray:
    """[C] False: no AB3DMOT setting is known to fail without a run."""
    return np.zeros(len(table), bool)


def setting_problem(what: str, params: Params, options: Options) -> str | None:
    """Why one setting is refused (``TrackerFamily.setting_problem``): ``boxes = false``; None when it runs."""
    return None if options.boxes else f"{what}: {BOXES_PROBLEM}"


def lane_keys(res: TrackResult, base) -> list[bytes]:
    """One digest per lane of what its rows carry (``TrackerFamily.lane_keys``): ``base`` (its ids
    and image boxes) and, per row, its detection (``src3``) and its 3D box; with a distortion, the
    lane's levels and seed (which detections its rows read)."""
    ids = np.asarray(res.ids)
    src = np.asarray(res.src3)
    out = []
    for b in range(ids.shape[0]):
        h = hashlib.sha1(b"ab3dmot")
        h.update(base[b])
        if res.distortion is not None:
            h.update(res.distortion.key(b))
        h.update(src[b][ids[b] >= 0].astype(np.int32).tobytes())
        h.update(np.ascontiguousarray(lane_values(res.box3, ids, b)).tobytes())
        out.append(h.digest())
    return out


#: AB3DMOT, the family ``"ab3dmot"``
FAMILY = TrackerFamily(
    config=FAMILY_CONFIG, init=tracker.init, step=tracker.step, run_batch=batch.run, track=track,
    prepare_frames=prepare_frames, compact_split=compact_split, default_capacity=default_capacity,
    output_slots=output_slots, rows=rows, row_arrays=row_arrays, class_run=class_run, write_runs=write_runs,
    table_problem=table_problem, failing_rows=failing_rows, setting_problem=setting_problem, lane_keys=lane_keys,
    box_format="f6",
    oracle="dfrmot_jax.testing.ab3dmot_oracle", distortion_spec=distortion_spec)

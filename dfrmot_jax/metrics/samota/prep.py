"""Inputs of the AB3DMOT KITTI metrics: ground truth, result files and seqmaps, read by its rules.

:mod:`dfrmot_jax.metrics.samota.evaluate` scores what this module reads. The reference is
``scripts/KITTI/evaluate.py`` of xinshuoweng/AB3DMOT (``trackingEvaluation._loadData``); its rules:

* **Rows of a class.** A row is loaded when its lower-cased type *contains* one of the class's
  names: ``car`` -> ``car``, ``van``; ``pedestrian`` -> ``pedestrian``, ``person_sitting``; both
  also ``dontcare`` (``Car``, ``car_2``, ``Van``, ``DontCare`` for car). Rows with track id -1
  are skipped unless typed DontCare. Frames and ids are ``int(float(s))`` (truncated).
* **Ground truth** (``label_02/SSSS.txt``, the strict KITTI reader): DontCare rows are the
  DontCare regions; every other loaded row is a ground-truth object, *ignored* (neither TP nor FN)
  when occluded > 2, truncated > 0, or of the neighbouring class (van for car, person_sitting for
  pedestrian). Its trajectory is its track id within the sequence.
* **Result rows.** ``frame id type truncated occluded alpha x1 y1 x2 y2 h w l x y z rot_y
  [score]``: 17 or 18 whitespace-separated columns (17: score -1, as the reference); the
  reference splits on single spaces, any whitespace is accepted here. A tracker row of the
  neighbouring class (``Van`` for car) is kept and, when unmatched, ignored.

Refused with file, line and field (:class:`~dfrmot_jax.io.kitti.KittiFormatError`), where the
reference crashes, refuses the class silently or would score nonsense: a kept row without 17 or 18
columns or with a non-number; a frame, id, image-box coordinate or score that is not finite; a
negative frame, a frame past the ground truth's end (``max label frame + 1``; the reference
silently skips such rows while their scores still enter their track's mean); a negative id other
than -1 (the reference keeps it as a track and miscounts it); a DontCare row in a result file (the
reference would score it as a tracker box); the same id twice in one frame (the reference
refuses the whole evaluation).

**3D fields** (read only when ``need_3d``; 2D evaluation reads but does not check them, as the
reference): ``h w l = -1 -1 -1`` with ``x y z = -1000 -1000 -1000`` is the placeholder of a
2D-only row: it has no 3D box and is never matched in 3D (its 3D IoU is 0 in the reference too),
so it counts as a false positive unless ignored. Otherwise the seven fields must be finite, with
``h > 0`` and ``w``, ``l`` non-zero and of the same sign: ``-w -l`` (the published DFR-FastMOT
files write ``h -w -l``: the box turned by 180 degrees) is the same box, as in the reference,
whose volume ``w * l * h`` is then positive. A zero size, ``h <= 0`` or ``w``, ``l`` of opposite
signs (the reference's volume would be zero or negative) is refused with the field named.

**Seqmaps** (KITTI's ``evaluate_tracking.seqmap``): ``NAME empty FIRST LAST`` a line; the
reference allots ``LAST - FIRST + 1`` frames. Refused with file, line and field: a line that is
not four fields, a sequence without a ground-truth file, and a frame count short of the ground
truth's frames.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import NamedTuple, Sequence

import numpy as np

from dfrmot_jax.io.kitti import KittiFormatError, quoted, read_text_file, read_tracking_labels
from dfrmot_jax.io.memo import FileMemo, file_stamps
from dfrmot_jax.metrics.common.fields3d import (PLACEHOLDER_DIMS, PLACEHOLDER_LOC, box3d_problem, parse_floats,
                                                placeholder_rows)
from dfrmot_jax.metrics.common.pairs import segment_starts
from dfrmot_jax.metrics.common.sequences import seq_name

__all__ = ["AB3D_CLASSES", "Ab3dGT", "Ab3dTracker", "prepare_ab3dmot_gt", "cached_ab3dmot_gt",
           "read_ab3dmot_results", "read_seqmap", "clear_cache", "PLACEHOLDER_DIMS", "PLACEHOLDER_LOC"]

#: evaluated class -> (names a type must contain to be loaded, the neighbouring class's type)
AB3D_CLASSES = {"car": (("car", "van", "dontcare"), "van"),
                "pedestrian": (("pedestrian", "person_sitting", "dontcare"), "person_sitting")}
MAX_TRUNCATION, MAX_OCCLUSION, MIN_HEIGHT = 0, 2, 25
_NAMES = ("frame", "track_id", "type", "truncated", "occluded", "alpha", "x1", "y1", "x2", "y2",
          "h", "w", "l", "x", "y", "z", "rot_y", "score")


def _loaded(types: np.ndarray, cls: str) -> np.ndarray:
    """[R] lower-cased type names -> [R] bool: loaded for ``cls`` (substring rule)."""
    names = AB3D_CLASSES[cls][0]
    out = np.zeros(len(types), dtype=bool)
    for n in names:
        out |= np.char.find(types.astype(str), n) >= 0
    return out


def _check_class(cls: str) -> str:
    c = str(cls).lower()
    if c not in AB3D_CLASSES:
        raise ValueError(f"class {cls!r} is not evaluatable by AB3DMOT's KITTI metrics ({', '.join(AB3D_CLASSES)})")
    return c


@dataclass(eq=False)
class Ab3dGT:
    """Ground truth of one class and sequence list, prepared once for every result folder and pass.

    ``sequences`` S names; ``lengths`` [S] frames (max label frame + 1); ``offsets`` [S+1]
    (sequence s owns global frames ``offsets[s]:offsets[s+1]``, F in total).
    Objects (N, by global frame, file order within a frame): ``frame`` [N], ``traj`` [N] global
    trajectory (one per (sequence, track id)), ``ignored`` [N] bool, ``box`` [N, 4] image box,
    ``box3d`` [N, 7] ``h w l x y z rot_y``; ``start`` [F+1]. DontCare regions (D): ``dc_box``
    [D, 4], ``dc_start`` [F+1]. ``traj_order`` [N]: objects by (trajectory, frame).
    """

    cls: str
    sequences: tuple
    lengths: np.ndarray
    offsets: np.ndarray
    frame: np.ndarray
    traj: np.ndarray
    ignored: np.ndarray
    box: np.ndarray
    box3d: np.ndarray
    start: np.ndarray
    dc_box: np.ndarray
    dc_start: np.ndarray
    traj_order: np.ndarray
    root: str = ""

    @property
    def n_frames(self) -> int:
        return int(self.offsets[-1])

    def __repr__(self) -> str:
        return (f"Ab3dGT(cls={self.cls!r}, sequences={len(self.sequences)}, frames={self.n_frames}, "
                f"objects={len(self.frame)}, ignored={int(self.ignored.sum())})")


def read_seqmap(path, root=None) -> tuple:
    """A KITTI seqmap (``NAME empty FIRST LAST`` a line) -> tuple of sequence names, file order.

    With ``root`` each sequence must have ``root/label_02/NAME.txt`` and ``LAST - FIRST + 1`` must
    cover its ground truth's frames; errors name file, line and field."""
    text = read_text_file(path)
    names = []
    for line, raw in zip(text.line_numbers, text.lines):
        f = raw.split()
        if len(f) != 4:
            raise KittiFormatError(text.path, line, None, f"expected 4 fields (NAME empty FIRST LAST), got {len(f)}")
        try:
            first, last = int(f[2]), int(f[3])
        except ValueError:
            raise KittiFormatError(text.path, line, "frames", f"not integers: {f[2]!r} {f[3]!r}") from None
        try:
            name = f"{int(f[0]):04d}"
        except ValueError:
            name = f[0]
        if name in names:
            raise KittiFormatError(text.path, line, "sequence", f"sequence {name} listed twice")
        if root is not None:
            label = Path(root) / "label_02" / f"{name}.txt"
            if not label.is_file():
                raise KittiFormatError(text.path, line, "sequence", f"no ground truth for sequence {name} ({label})")
            fr = read_tracking_labels(label).frame
            need = int(fr.max()) + 1 if fr.size else 0
            if last - first + 1 < need:
                raise KittiFormatError(text.path, line, "frames", f"{last - first + 1} frames ({first}..{last}), but the "
                                       f"ground truth of sequence {name} has frames 0..{need - 1}")
        names.append(name)
    if not names:
        raise KittiFormatError(text.path, None, None, "no sequence listed")
    return tuple(names)


def prepare_ab3dmot_gt(root, cls: str = "car", sequences: Sequence | None = None) -> Ab3dGT:
    """Read ``root/label_02`` for ``cls`` by AB3DMOT's rules (module docstring) -> :class:`Ab3dGT`.

    sequences: names or ints, default every ``label_02/*.txt``. A sequence without a label file
    raises :class:`KittiFormatError`."""
    cls = _check_class(cls)
    neighbour = AB3D_CLASSES[cls][1]
    label_dir = Path(root) / "label_02"
    names = (sorted(p.stem for p in label_dir.glob("*.txt")) if sequences is None
             else [seq_name(s) for s in sequences])
    if not names:
        raise FileNotFoundError(f"no ground truth files in {label_dir}")
    lengths, frames, trajs, ign, boxes, boxes3d, dcf, dcb = [], [], [], [], [], [], [], []
    offset = n_traj = 0
    for name in names:
        path = label_dir / f"{name}.txt"
        if not path.is_file():
            raise KittiFormatError(path, None, None, f"no ground truth for sequence {name}")
        lab = read_tracking_labels(path)
        length = int(lab.frame.max()) + 1 if lab.frame.size else 0
        lengths.append(length)
        types = np.char.lower(lab.type.astype(str)) if lab.type.size else np.zeros(0, dtype=str)
        is_dc = types == "dontcare"
        use = _loaded(types, cls) & ((lab.track_id != -1) | is_dc)
        obj = np.flatnonzero(use & ~is_dc)
        obj = obj[np.argsort(lab.frame[obj], kind="stable")]
        uniq, inv = np.unique(lab.track_id[obj], return_inverse=True)
        frames.append(lab.frame[obj] + offset)
        trajs.append(inv.reshape(-1) + n_traj)
        trunc = np.trunc(lab.truncated[obj])
        occ = np.trunc(lab.occluded[obj])
        ign.append((occ > MAX_OCCLUSION) | (trunc > MAX_TRUNCATION) | (types[obj] == neighbour))
        boxes.append(lab.box[obj])
        boxes3d.append(np.concatenate([lab.dims[obj], lab.loc[obj], lab.rot_y[obj, None]], axis=1))
        dc = np.flatnonzero(use & is_dc)
        dc = dc[np.argsort(lab.frame[dc], kind="stable")]
        dcf.append(lab.frame[dc] + offset)
        dcb.append(lab.box[dc])
        offset += length
        n_traj += len(uniq)
    lengths_a = np.asarray(lengths, dtype=np.int64)
    offsets = segment_starts(lengths_a)
    F = int(offsets[-1])
    frame = np.concatenate(frames).astype(np.int64)
    traj = np.concatenate(trajs).astype(np.int64)
    dc_frame = np.concatenate(dcf).astype(np.int64)
    return Ab3dGT(cls=cls, sequences=tuple(names), lengths=lengths_a, offsets=offsets, frame=frame, traj=traj,
                  ignored=np.concatenate(ign).astype(bool), box=np.concatenate(boxes).reshape(-1, 4),
                  box3d=np.concatenate(boxes3d).reshape(-1, 7), start=segment_starts(np.bincount(frame, minlength=F)),
                  dc_box=np.concatenate(dcb).reshape(-1, 4),
                  dc_start=segment_starts(np.bincount(dc_frame, minlength=F)),
                  traj_order=np.lexsort((frame, traj)), root=str(root))


_GT_CACHE = FileMemo()


def cached_ab3dmot_gt(root, cls: str = "car", sequences: Sequence | None = None) -> Ab3dGT:
    """:func:`prepare_ab3dmot_gt` memoised. Key: (root, class, sequences); stamp: the sequences' label
    files (:class:`~dfrmot_jax.io.memo.FileMemo`): all that AB3DMOT's ground truth is read from."""
    if isinstance(root, Ab3dGT):
        return root
    label_dir = Path(root) / "label_02"
    names = (tuple(sorted(p.stem for p in label_dir.glob("*.txt"))) if sequences is None
             else tuple(seq_name(s) for s in sequences))
    stamp = file_stamps(label_dir / f"{n}.txt" for n in names)
    key = (str(Path(root).resolve()), str(cls).lower(), names)
    return _GT_CACHE.get(key, stamp, lambda: prepare_ab3dmot_gt(root, cls, names))


def clear_cache() -> None:
    """Forget the memoised ground truth (a cold start)."""
    _GT_CACHE.clear()


class Ab3dTracker(NamedTuple):
    """Tracker rows of one result folder for one class (M rows, by global frame, file order within).

    frame [M] global frame; track [M] global track index (one per (sequence, id)); n_tracks;
    neighbour [M] bool (typed as the neighbouring class); box [M, 4]; box3d [M, 7]; has3d [M]
    bool (False: the 2D-only placeholder, or 3D not read); score [M] float64 as written (-1 for
    17 columns); source [M] data-row index in its file; seq [M]; paths: per sequence the file or None.
    """

    frame: np.ndarray
    track: np.ndarray
    n_tracks: int
    neighbour: np.ndarray
    box: np.ndarray
    box3d: np.ndarray
    has3d: np.ndarray
    score: np.ndarray
    source: np.ndarray
    seq: np.ndarray
    paths: tuple


def _read_file(path, cls: str, length: int, name: str, need_3d: bool) -> dict:
    """One result file -> dict of the loaded rows' columns (file order); raises KittiFormatError."""
    text = read_text_file(path)
    split = [s.split() for s in text.lines]
    count = np.fromiter(map(len, split), dtype=np.int64, count=len(split))

    def fail(r: int, j: int | None, message: str):
        raise KittiFormatError(text.path, text.line_numbers[r], None if j is None else _NAMES[j], message)

    if np.any(count < 3):
        r = int(np.argmax(count < 3))
        fail(r, None, f"expected 17 or 18 columns, got {count[r]}")
    types = np.char.lower(np.array([s[2] for s in split], dtype=str)) if split else np.zeros(0, dtype=str)
    rows = np.flatnonzero(_loaded(types, cls))
    bad = np.flatnonzero((count[rows] != 17) & (count[rows] != 18))
    if bad.size:
        r = int(rows[bad[0]])
        fail(r, None, f"expected 17 or 18 columns (frame id type truncated occluded alpha x1 y1 x2 y2 h w l x y z "
                      f"rot_y [score]), got {count[r]}")
    tok = np.full((len(rows), 18), "-1", dtype=object)
    for k, r in enumerate(rows.tolist()):
        tok[k, :count[r]] = split[r]
    cols = {}
    for j in (0, 1) + tuple(range(3, 18)):
        v, ok = parse_floats(tok[:, j].astype(str))
        if not ok.all():
            k = int(np.argmin(ok))
            fail(int(rows[k]), j, f"not a number: {quoted(tok[k, j])}")
        cols[j] = v
    frame_f, tid_f = cols[0], cols[1]
    for j in (0, 1, 6, 7, 8, 9, 17):
        nf = ~np.isfinite(cols[j])
        if nf.any():
            k = int(np.argmax(nf))
            fail(int(rows[k]), j, f"not finite: {quoted(tok[k, j])}")
    frame = np.trunc(frame_f).astype(np.int64)
    tid = np.trunc(tid_f).astype(np.int64)
    is_dc = types[rows] == "dontcare"
    if is_dc.any():
        fail(int(rows[np.argmax(is_dc)]), 2, "a DontCare row in a result file (AB3DMOT's evaluator would score it "
                                             "as a tracker box)")
    keep = tid != -1
    rows, frame, tid = rows[keep], frame[keep], tid[keep]
    cols = {j: v[keep] for j, v in cols.items()}
    tok = tok[keep]
    for mask, j, msg in ((frame < 0, 0, lambda k: f"negative frame {quoted(tok[k, 0])}"),
                         (frame >= length, 0, lambda k: f"frame {frame[k]} is past the ground truth's end (sequence "
                                                        f"{name}: frames 0..{length - 1})"),
                         (tid < 0, 1, lambda k: f"negative id {quoted(tok[k, 1])} (only -1, a row to skip, is "
                                                f"allowed)")):
        if mask.any():
            k = int(np.argmax(mask))
            fail(int(rows[k]), j, msg(k))
    if len(rows):
        order = np.lexsort((rows, tid, frame))
        dup = (frame[order][1:] == frame[order][:-1]) & (tid[order][1:] == tid[order][:-1])
        if dup.any():
            k = int(order[1:][np.argmax(dup)])
            fail(int(rows[k]), 1, f"id {tid[k]} occurs twice in frame {frame[k]}")
    dims = np.stack([cols[10], cols[11], cols[12]], axis=1)
    loc = np.stack([cols[13], cols[14], cols[15]], axis=1)
    box3d = np.concatenate([dims, loc, cols[16][:, None]], axis=1)
    placeholder = placeholder_rows(box3d)
    if need_3d:
        bad = box3d_problem(box3d, ~placeholder)
        if bad is not None:
            k, j, msg = bad
            fail(int(rows[k]), 10 + j, msg.format(quoted(tok[k, 10 + j]), quoted(tok[k, 12])))
    score = np.where(count[rows] == 18, cols[17], -1.0)
    return dict(frame=frame, tid=tid, neighbour=types[rows] == AB3D_CLASSES[cls][1],
                box=np.stack([cols[6], cols[7], cols[8], cols[9]], axis=1), box3d=box3d,
                has3d=~placeholder if need_3d else np.zeros(len(rows), dtype=bool), score=score, source=rows)


def read_ab3dmot_results(results_dir, gt: Ab3dGT, need_3d: bool = True, missing: str = "empty") -> Ab3dTracker:
    """Read ``results_dir/SSSS.txt`` for every sequence of ``gt`` by AB3DMOT's rules (module docstring).

    need_3d: check and keep the 3D boxes (3D IoU); False reads them unchecked (2D IoU). missing: a
    sequence without a file is an empty output (``'empty'``: the reference with an empty file) or
    an error (``'error'``). Returns :class:`Ab3dTracker`; raises :class:`KittiFormatError`.
    """
    results_dir = Path(results_dir)
    if not results_dir.is_dir():
        raise FileNotFoundError(f"results folder not found: {results_dir}")
    parts, paths = [], []
    n_tracks = 0
    for s, name in enumerate(gt.sequences):
        path = results_dir / f"{name}.txt"
        if path.exists() and not path.is_file():
            raise KittiFormatError(path, None, None, "not a regular file, not a result file")
        if not path.is_file():
            if missing == "error":
                raise KittiFormatError(path, None, None, "result file not found")
            paths.append(None)
            continue
        paths.append(str(path))
        d = _read_file(path, gt.cls, int(gt.lengths[s]), name, need_3d)
        order = np.argsort(d["frame"], kind="stable")
        d = {k: v[order] for k, v in d.items()}
        uniq, inv = np.unique(d["tid"], return_inverse=True)
        d["track"] = inv.reshape(-1) + n_tracks
        n_tracks += len(uniq)
        d["frame"] = d["frame"] + gt.offsets[s]
        d["seq"] = np.full(len(order), s, dtype=np.int64)
        parts.append(d)

    def cat(key, shape, dtype):
        return np.concatenate([p[key] for p in parts]).astype(dtype) if parts else np.zeros(shape, dtype)

    return Ab3dTracker(frame=cat("frame", 0, np.int64), track=cat("track", 0, np.int64), n_tracks=n_tracks,
                       neighbour=cat("neighbour", 0, bool), box=cat("box", (0, 4), np.float64),
                       box3d=cat("box3d", (0, 7), np.float64), has3d=cat("has3d", 0, bool),
                       score=cat("score", 0, np.float64), source=cat("source", 0, np.int64),
                       seq=cat("seq", 0, np.int64), paths=tuple(paths))

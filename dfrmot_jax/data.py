"""A KITTI split packed into padded arrays: all sequences concatenated along time.

``load_split`` reads detections for many sequences and packs them (host numpy) into a ``Split``:
detections ``[T, M2]`` (2D) and ``[T, M3]`` (3D) with masks, ``T`` the total frame count of the
split, a ``reset`` flag on each sequence's first frame. Family-free: each tracker family turns a split
into its own device inputs (DFR-FastMOT's ``trackers.dfr.frames.prepare_frames``).
"""

from __future__ import annotations

from pathlib import Path
from typing import NamedTuple

import numpy as np

from .geometry import KITTI_IMAGE_SIZE, box3d_extent, project_box3d_to_image
from .io.kitti import (
    Detections2D,
    Detections3D,
    KittiFormatError,
    line_of_row,
    read_calib,
    read_detections_2d,
    read_detections_3d,
    read_tracking_labels,
    sequence_lengths,
)
from .io.memo import FileMemo, file_stamps
from .io.sequence import SequenceDets  # public here too: load_sequences returns it, pack takes it
from .lidar_settings import LiftSettings
from .lidar.scans import scan_stamps
from .lidar.source import lidar_dir, lift_sequence
from .paths import missing_data_message

CLASS_NAMES = {"car": "Car", "pedestrian": "Pedestrian"}
DEFAULT_IMAGE_SIZE = KITTI_IMAGE_SIZE        # (width, height) of camera 02, defined in geometry
# The type column of 3D detection files: AB3DMOT's integer codes (the PointRCNN and PointGNN files:
# car files use 2, pedestrian files 1) or KITTI class names (the 17-column label layout).
TYPE_CODES_3D = {1: "pedestrian", 2: "car", 3: "cyclist"}
TYPE_NAMES_3D = frozenset({"car", "van", "truck", "pedestrian", "person", "person_sitting", "cyclist", "tram",
                           "misc", "dontcare"})


class Split(NamedTuple):
    """Many sequences packed along time (host numpy arrays).

    names [S], lengths [S], offsets [S]: sequence s owns global frames offsets[s] .. offsets[s]+lengths[s]-1.
    reset [T] bool (first frame of a sequence), seq [T] int32, frame [T] int32 (frame within sequence).
    box2d [T, M2, 4] f64, score2d [T, M2] f64, valid2d [T, M2] bool, row2d [T, M2] int32 (file row).
    box3d [T, M3, 4] f64 (the 3D detector's image box), proj3d [T, M3, 4] f64 (its 8 corners projected
    with P2, clipped), score3d [T, M3], dims3d [T, M3, 3] (h, w, l), loc3d [T, M3, 3] (x, y, z),
    rot_y3d [T, M3], alpha3d [T, M3], valid3d [T, M3] bool, row3d [T, M3] int32 (row in the sequence's
    ``det3d``: the file row, unless the loader dropped 3D rows of another class).
    cls: the class tracked; root: the KITTI root it was read from (its ground truth seeds
    distortion studies).
    """

    names: tuple[str, ...]
    lengths: np.ndarray
    offsets: np.ndarray
    reset: np.ndarray
    seq: np.ndarray
    frame: np.ndarray
    box2d: np.ndarray
    score2d: np.ndarray
    valid2d: np.ndarray
    row2d: np.ndarray
    box3d: np.ndarray
    proj3d: np.ndarray
    score3d: np.ndarray
    dims3d: np.ndarray
    loc3d: np.ndarray
    rot_y3d: np.ndarray
    alpha3d: np.ndarray
    valid3d: np.ndarray
    row3d: np.ndarray
    cls: str = "car"
    root: str = ""

    @property
    def n_frames(self) -> int:
        return int(self.reset.shape[0])

    def sequence_slice(self, s: int) -> slice:
        return slice(int(self.offsets[s]), int(self.offsets[s] + self.lengths[s]))


def detection_dir(root: Path, detector: str | Path, cls: str) -> Path:
    """A detector given by name (``ROOT/detections/<name>/<class>/``) or as a directory path: one
    holding a folder per class (``<dir>/<class>/``), else the folder of the sequence files itself."""
    by_name = Path(root) / "detections" / str(detector) / cls
    if by_name.is_dir():
        return by_name
    as_path = Path(detector)
    for d in (as_path / cls, as_path):
        if d.is_dir():
            return d
    if not (Path(root) / "detections").is_dir():
        raise KittiFormatError(str(detector), None, None, f"not a directory, and {missing_data_message(root)}")
    known = sorted(p.name for p in (Path(root) / "detections").glob("*") if p.is_dir())
    raise KittiFormatError(str(by_name), None, None,
                           f"unknown detector {str(detector)!r}: not a directory; detectors under the root: {known}")


def sequences_with_class(root: Path, cls: str) -> list[str]:
    """Sequences whose ground truth has at least one object of the class (car: 20 of 21)."""
    name = CLASS_NAMES[cls]
    out = []
    for f in sorted((Path(root) / "label_02").glob("*.txt")):
        labels = read_tracking_labels(f)
        if np.any(labels.type == name):
            out.append(f.stem)
    return out


def _type_class_3d(token: str) -> str | None:
    """A 3D detection's type token -> class name (lower case), None when not a known type."""
    t = str(token).strip()
    try:
        v = float(t)
    except ValueError:
        name = t.lower()
        return name if name in TYPE_NAMES_3D else None
    return TYPE_CODES_3D.get(int(v)) if v == int(v) else None


def class_rows_3d(det: Detections3D, cls: str, path=None) -> np.ndarray:
    """[R] bool: the rows of a 3D detection file whose ``type`` is the class ``cls``.

    Types are AB3DMOT's codes (``1`` pedestrian, ``2`` car, ``3`` cyclist; ``2.0`` is 2) or KITTI
    class names (any case). Rows of another known type (e.g. a cyclist in a car file) are not the
    class; an unknown type (e.g. ``7``) raises :class:`KittiFormatError` (file, line, field ``type``)
    rather than being guessed.
    """
    out = np.zeros(det.frame.size, dtype=bool)
    if not det.frame.size:
        return out
    uniq, inv = np.unique(det.type.astype(str), return_inverse=True)
    inv = inv.reshape(-1)
    for k, tok in enumerate(uniq):
        name = _type_class_3d(tok)
        if name is None:
            row = int(np.flatnonzero(inv == k)[0])
            raise KittiFormatError(str(path), line_of_row(path, row), "type",
                                   f"unknown 3D detection type {str(tok)!r} (expected AB3DMOT codes 1 = Pedestrian, "
                                   f"2 = Car, 3 = Cyclist, or a KITTI class name)")
        if name == cls:
            out[inv == k] = True
    return out


def load_sequences(root, det2d, det3d, cls: str = "car", sequences=None,
                   image_size=DEFAULT_IMAGE_SIZE, lift: LiftSettings | None = None) -> list[SequenceDets]:
    """Read detections and calib of each sequence (default: those whose ground truth has the class).
    ``det2d=None``: no 2D detections (every sequence's are empty), for a tracker that reads 3D ones only;
    ``det3d=None``: no 3D detections, for a tracker that reads 2D ones only (a camera-only family).

    A root without ``label_02/`` raises ValueError (the KITTI root is wrong), a missing detection or
    calib file :class:`KittiFormatError` (``file not found``); an empty file is a sequence without
    detections. 3D rows whose ``type`` is another class are dropped (:func:`class_rows_3d`; on the
    shipped PointRCNN / PointGNN files every row is the folder's class).

    ``det3d="lidar:DIR"``: the 3D detections are the 2D ones lifted from the scans
    ``DIR/velodyne/SSSS/FFFFFF.bin`` with the settings ``lift`` (default ``LiftSettings()``), cached
    per setting (:func:`dfrmot_jax.lidar.lift_sequence`); each belongs to its 2D detection.
    """
    root = Path(root)
    if cls not in CLASS_NAMES:
        raise ValueError(f"class {cls!r}: expected one of {sorted(CLASS_NAMES)}")
    if not (root / "label_02").is_dir():
        raise ValueError(missing_data_message(root))
    d2 = None if det2d is None else detection_dir(root, det2d, cls)
    scans = None if det3d is None else lidar_dir(det3d)
    if d2 is None and scans is not None:
        raise ValueError(f"det3d={det3d!r} lifts the 2D detections: give det2d")
    if d2 is None and det3d is None:
        raise ValueError("no detections to read: give det2d, det3d or both")
    d3 = None if scans is not None or det3d is None else detection_dir(root, det3d, cls)
    if sequences is None:
        sequences = sequences_with_class(root, cls)
    lengths = sequence_lengths(root, sequences)
    out = []
    for name in sequences:
        if d2 is None:          # (a tracker that reads 3D detections only)
            p2, det2 = None, Detections2D(np.zeros(0, np.int64), np.zeros((0, 4)), np.zeros(0))
        else:
            p2 = d2 / f"{name}.txt"
            det2 = read_detections_2d(p2)
        calib_path = root / "calib" / f"{name}.txt"
        calib = read_calib(calib_path)
        checks = [("2D", det2, p2)] if p2 is not None else []
        if d3 is None and scans is None:        # (a tracker that reads 2D detections only)
            p3, det3 = None, Detections3D(*(np.zeros((0,) + shape, dtype) for shape, dtype in (
                ((), np.int64), ((), object), ((4,), np.float64), ((), np.float64), ((3,), np.float64),
                ((3,), np.float64), ((), np.float64), ((), np.float64))))
        elif scans is None:
            p3 = d3 / f"{name}.txt"
            det3 = read_detections_3d(p3)
            checks.append(("3D", det3, p3))
        for kind, det, path in checks:
            beyond = det.frame >= lengths[name]
            if beyond.any():
                row = int(np.argmax(beyond))
                raise KittiFormatError(str(path), line_of_row(path, row), "frame",
                                       f"{kind} detection at frame {int(det.frame[row])} beyond the sequence "
                                       f"({lengths[name]} frames)")
        if scans is not None:
            det3 = lift_sequence(scans, name, lengths[name], det2, calib, lift or LiftSettings(), cls)
            out.append(SequenceDets(name=name, n_frames=lengths[name], det2d=det2, det3d=det3, calib=calib,
                                    fused3d=True))
            continue
        keep = class_rows_3d(det3, cls, p3) if p3 is not None else np.ones(0, bool)
        if not keep.all():
            det3 = Detections3D(*(np.asarray(v)[keep] for v in det3))
        out.append(SequenceDets(name=name, n_frames=lengths[name], det2d=det2, det3d=det3, calib=calib))
    return out


def _rows_by_frame(frames: np.ndarray, n_frames: int) -> tuple[np.ndarray, np.ndarray]:
    """Slot of each row within its frame and the per-frame counts."""
    counts = np.bincount(frames, minlength=n_frames)
    starts = np.concatenate([[0], np.cumsum(counts)[:-1]])
    slot = np.arange(frames.size) - starts[frames]
    return slot, counts


#: what an empty detection slot holds, per Split field (``pack``, ``compact_split``)
PAD_2D = {"box2d": 0.0, "score2d": 0.0, "row2d": -1}
PAD_3D = {"box3d": 0.0, "proj3d": 0.0, "score3d": 0.0, "dims3d": 1.0, "loc3d": (0.0, 0.0, 10.0), "rot_y3d": 0.0,
           "alpha3d": 0.0, "row3d": -1}


def pack(seqs: list[SequenceDets], cls: str = "car", image_size=DEFAULT_IMAGE_SIZE,
         min_slots: int = 1) -> Split:
    """Pack sequences into a ``Split`` (M2, M3 = the largest detection counts of any frame)."""
    lengths = np.array([s.n_frames for s in seqs], dtype=np.int64)
    offsets = np.concatenate([[0], np.cumsum(lengths)[:-1]]).astype(np.int64)
    T = int(lengths.sum())
    per2, per3 = [], []
    for s in seqs:
        per2.append(_rows_by_frame(s.det2d.frame, s.n_frames))
        per3.append(_rows_by_frame(s.det3d.frame, s.n_frames))
    m2 = max([min_slots] + [int(c.max(initial=0)) for _, c in per2])
    m3 = max([min_slots] + [int(c.max(initial=0)) for _, c in per3])

    pads = {**PAD_2D, **PAD_3D}

    def empty(field: str, m: int, *width: int, dtype=np.float64) -> np.ndarray:
        return np.full((T, m, *width), pads[field], dtype)

    box2d, score2d, row2d = empty("box2d", m2, 4), empty("score2d", m2), empty("row2d", m2, dtype=np.int32)
    box3d, proj3d, score3d = empty("box3d", m3, 4), empty("proj3d", m3, 4), empty("score3d", m3)
    dims3d, loc3d = empty("dims3d", m3, 3), empty("loc3d", m3, 3)
    rot_y3d, alpha3d, row3d = empty("rot_y3d", m3), empty("alpha3d", m3), empty("row3d", m3, dtype=np.int32)
    valid2d, valid3d = np.zeros((T, m2), bool), np.zeros((T, m3), bool)
    reset = np.zeros(T, bool); seq = np.zeros(T, np.int32); frame = np.zeros(T, np.int32)
    for k, s in enumerate(seqs):
        o = int(offsets[k])
        reset[o] = True
        seq[o:o + s.n_frames] = k
        frame[o:o + s.n_frames] = np.arange(s.n_frames)
        slot, _ = per2[k]
        t = o + s.det2d.frame
        box2d[t, slot] = s.det2d.box; score2d[t, slot] = s.det2d.score; valid2d[t, slot] = True
        row2d[t, slot] = np.arange(s.det2d.frame.size)
        slot, _ = per3[k]
        d = s.det3d
        t = o + d.frame
        box3d[t, slot] = d.box; score3d[t, slot] = d.score; valid3d[t, slot] = True
        dims3d[t, slot] = d.dims; loc3d[t, slot] = d.loc; rot_y3d[t, slot] = d.rot_y; alpha3d[t, slot] = d.alpha
        row3d[t, slot] = np.arange(d.frame.size)
        if d.frame.size:
            proj3d[t, slot] = d.box if s.fused3d else project_box3d_to_image(d.dims, d.loc, d.rot_y, s.calib.P2,
                                                                              image_size)
    return Split(names=tuple(s.name for s in seqs), lengths=lengths, offsets=offsets, reset=reset, seq=seq,
                 frame=frame, box2d=box2d, score2d=score2d, valid2d=valid2d, row2d=row2d, box3d=box3d,
                 proj3d=proj3d, score3d=score3d, dims3d=dims3d, loc3d=loc3d, rot_y3d=rot_y3d, alpha3d=alpha3d,
                 valid3d=valid3d, row3d=row3d, cls=cls)


def load_split(root, det2d="rrc", det3d="pointrcnn", cls: str = "car", sequences=None,
               image_size=DEFAULT_IMAGE_SIZE, lift: LiftSettings | None = None) -> Split:
    """Read and pack a split: ``load_split(root, "rrc", "pointrcnn", "car")``; with LiDAR scans
    ``load_split(root, "rrc", "lidar:DIR", "car", lift=LiftSettings(shrink=0.1))``."""
    return pack(load_sequences(root, det2d, det3d, cls, sequences, image_size, lift), cls, image_size)._replace(
        root=str(root))


_SPLITS = FileMemo(size=4)


def cached_split(root, det2d, det3d, cls: str, sequences, lift: LiftSettings | None = None) -> Split:
    """:func:`load_split` memoised: sweeps on the same data, such as a tune's batches, read it once.
    Key: every argument (root, detectors, class, sequences, the lifting settings; the image size is
    always the default's). Stamp (:class:`~dfrmot_jax.io.memo.FileMemo`): every file the split is read
    from (labels for the lengths, calibrations, both detectors' files; with ``det3d="lidar:DIR"``
    every scan, the 2D detections and calibrations being what is lifted)."""
    root = Path(root)
    sequences = tuple(sequences)
    files = [root / sub / f"{s}.txt" for sub in ("label_02", "calib") for s in sequences]
    scans = None if det3d is None else lidar_dir(det3d)
    for det in [d for d in ((det2d,) if scans is not None else (det2d, det3d)) if d is not None]:
        folder = detection_dir(root, det, cls)
        files += [folder / f"{s}.txt" for s in sequences]
    stamp = file_stamps(files)
    lift_key = None
    if scans is not None:
        lift_key = tuple((lift or LiftSettings()).validate())
        lengths = sequence_lengths(root, sequences)
        stamp += tuple(scan_stamps(scans, s, lengths[s]) for s in sequences)
    key = (str(root.resolve()), str(det2d), str(det3d), cls, sequences, lift_key)
    return _SPLITS.get(key, stamp, lambda: load_split(root, det2d, det3d, cls, list(sequences), lift=lift))


def compact_split(split: Split, score_2d: float, score_3d: float) -> Split:
    """The split without the detections that no setting with thresholds >= ``score_2d`` / ``score_3d``
    keeps (below them, or invalid), each frame's remaining detections packed to the front in their
    slot order and the slots cut to the most any frame keeps (M2' <= M2, M3' <= M3).

    Tracking gives the same ids and boxes for any such setting: a step keeps exactly the same
    detections (scores compared in float32, as the step does), and every tie-break orders by slot,
    which packing preserves. A batch's [objects, tracks] work shrinks with M2' + M3' (KITTI car at
    the grid's loosest thresholds: 14 + 19 slots -> 14 + 13). Output "detections" slots then index
    the compacted split (``row2d`` / ``row3d`` still name the file rows; :func:`compact_slots` gives
    the original slot of each).
    """
    return compact_slots(split, score_2d, score_3d)[0]


def compact_slots(split: Split, score_2d: float, score_3d: float) -> tuple[Split, np.ndarray, np.ndarray]:
    """:func:`compact_split` and where its slots come from: (split', order2 [T, M2'], order3
    [T, M3']), ``order[t, j]`` the original slot of frame t's compacted slot j (every original slot
    at most once per frame; padding slots name slots no setting keeps)."""
    fields: dict = {}
    kept = kept_slots(split, score_2d, score_3d)
    for (order, valid), valid_name, pads in zip(kept, ("valid2d", "valid3d"), (PAD_2D, PAD_3D)):
        fields[valid_name] = valid
        for name, pad in pads.items():
            fields[name] = take_slots(getattr(split, name), order, valid, pad)
    return split._replace(**fields), kept[0][0], kept[1][0]


def kept_slots(split: Split, score_2d: float, score_3d: float) -> tuple[tuple[np.ndarray, np.ndarray], ...]:
    """((order2, valid2), (order3, valid3)) of :func:`compact_slots`: ``order [T, M']`` each frame's
    kept slots (valid, score >= the threshold, compared in float32 as the step does) first, in slot
    order, cut to the most any frame keeps; ``valid [T, M']`` the compacted slot holds a kept one."""
    out = []
    for keep in (split.valid2d & (split.score2d.astype(np.float32) >= np.float32(score_2d)),
                 split.valid3d & (split.score3d.astype(np.float32) >= np.float32(score_3d))):
        m = max(1, int(keep.sum(axis=1).max(initial=0)))
        order = np.argsort(~keep, axis=1, kind="stable")[:, :m]          # kept slots first, in slot order
        out.append((order, np.take_along_axis(keep, order, axis=1)))
    return tuple(out)


def take_slots(a: np.ndarray, order: np.ndarray, valid: np.ndarray, pad) -> np.ndarray:
    """[T, M', ...] the values of ``a [T, M, ...]`` at each frame's slots ``order``, ``pad`` where not ``valid``."""
    t, m = a.shape[:2]
    flat = (order + (np.arange(t) * m)[:, None]).ravel()
    # one gather of whole slots (np.take: ~5x faster than fancy indexing on rows of several values)
    v = np.take(a.reshape((t * m,) + a.shape[2:]), flat, axis=0).reshape(order.shape + a.shape[2:])
    v[~valid] = np.asarray(pad, a.dtype)
    return v


# ---------------------------------------------------------------------------------------------
# Inputs of the scan for one set of static options



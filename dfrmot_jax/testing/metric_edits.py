"""Tracker outputs for parity tests and benchmarks: load, edit (seeded), write, pack into arrays.

A :class:`SeqResults` holds one sequence's result rows in file order (frame, id, type, box). The
``edit_*`` functions return edited copies; box values are kept float32-representable so the same
output can be written to text (``repr`` of the float64 value, read back bit-exactly) and packed
into the tracker's float32 ``[B, T, K, 4]`` arrays with identical numbers.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Mapping, Sequence

import numpy as np

from dfrmot_jax.io.kitti import read_tracking_labels
from dfrmot_jax.metrics.kitti2d.boxes import pair_iou

__all__ = ["SeqResults", "load_results", "write_results", "pack_arrays", "stress_edit", "naive_tracks",
           "f32"]


def f32(x) -> np.ndarray:
    """Round to the nearest float32 and back to float64 ([...] float64)."""
    return np.asarray(x, dtype=np.float32).astype(np.float64)


@dataclass
class SeqResults:
    """One sequence's tracker rows, file order. frame, track_id: [R] int64; type: [R] str; box: [R, 4] f64."""
    frame: np.ndarray
    track_id: np.ndarray
    type: np.ndarray
    box: np.ndarray

    def __len__(self) -> int:
        return len(self.frame)

    def take(self, idx) -> "SeqResults":
        return SeqResults(self.frame[idx], self.track_id[idx], self.type[idx], self.box[idx])

    def sorted(self) -> "SeqResults":
        return self.take(np.argsort(self.frame, kind="stable"))

    @staticmethod
    def empty() -> "SeqResults":
        return SeqResults(np.zeros(0, np.int64), np.zeros(0, np.int64), np.zeros(0, dtype="<U16"), np.zeros((0, 4)))

    @staticmethod
    def concat(parts: Sequence["SeqResults"]) -> "SeqResults":
        parts = [p for p in parts if len(p)]
        if not parts:
            return SeqResults.empty()
        return SeqResults(np.concatenate([p.frame for p in parts]), np.concatenate([p.track_id for p in parts]),
                          np.concatenate([p.type.astype("<U16") for p in parts]),
                          np.concatenate([p.box for p in parts]))


def load_results(results_dir, sequences: Sequence[str]) -> dict[str, SeqResults]:
    """Read ``results_dir/SSSS.txt`` (KITTI tracking results) for each sequence; missing = empty."""
    out = {}
    for s in sequences:
        p = Path(results_dir) / f"{s}.txt"
        if not p.is_file():
            out[s] = SeqResults.empty()
            continue
        lab = read_tracking_labels(p)
        out[s] = SeqResults(lab.frame.astype(np.int64), lab.track_id.astype(np.int64),
                            lab.type.astype("<U16"), lab.box.astype(np.float64))
    return out


def write_results(results_dir, results: Mapping[str, SeqResults], sequences: Sequence[str] | None = None) -> Path:
    """Write ``results_dir/SSSS.txt`` (18 columns, boxes as exact float64 repr); [] rows -> empty file."""
    d = Path(results_dir)
    d.mkdir(parents=True, exist_ok=True)
    for s in (sequences if sequences is not None else results):
        r = results.get(s, SeqResults.empty())
        lines = []
        for f, i, t, b in zip(r.frame.tolist(), r.track_id.tolist(), r.type.tolist(), r.box.tolist()):
            lines.append(f"{f} {i} {t} -1 -1 -10 {b[0]!r} {b[1]!r} {b[2]!r} {b[3]!r} "
                         "-1 -1 -1 -1000 -1000 -1000 -10 1\n")
        (d / f"{s}.txt").write_text("".join(lines))
    return d


def pack_arrays(lanes: Sequence[Mapping[str, SeqResults]], sequences: Sequence[str], lengths: Sequence[int],
                cls: str = "car", k: int | None = None) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Pack per-lane results into padded arrays, rows of a frame in file order along K.

    Only rows of class ``cls`` (case-insensitive; ``car_2`` counts as car) with id >= 0 are packed
    (other rows do not count in TrackEval's evaluation of ``cls``). Returns ids [B, T, K] int32
    (-1 empty), boxes [B, T, K, 4] float32, seq_offsets [S] int64 with T = sum(lengths).
    """
    lengths = np.asarray(lengths, dtype=np.int64)
    offsets = np.concatenate([[0], np.cumsum(lengths)])
    T = int(offsets[-1])
    names = {"car": ("car", "car_2"), "pedestrian": ("pedestrian",)}[cls]
    flat = []
    for lane in lanes:
        fr, ids, bx = [], [], []
        for s, name in enumerate(sequences):
            r = lane.get(name, SeqResults.empty())
            if not len(r):
                continue
            use = np.isin(np.char.lower(r.type.astype(str)), names) & (r.track_id >= 0)
            rr = r.take(np.flatnonzero(use))
            order = np.argsort(rr.frame, kind="stable")
            fr.append(rr.frame[order] + offsets[s])
            ids.append(rr.track_id[order])
            bx.append(rr.box[order])
        if fr:
            flat.append((np.concatenate(fr), np.concatenate(ids), np.concatenate(bx)))
        else:
            flat.append((np.zeros(0, np.int64), np.zeros(0, np.int64), np.zeros((0, 4))))
    kmax = max([int(np.bincount(f).max()) if len(f) else 0 for f, _, _ in flat] + [1])
    K = kmax if k is None else int(k)
    if K < kmax:
        raise ValueError(f"k={k} < max rows per frame {kmax}")
    B = len(lanes)
    ids_a = np.full((B, T, K), -1, dtype=np.int32)
    box_a = np.zeros((B, T, K, 4), dtype=np.float32)
    for b, (f, i, x) in enumerate(flat):
        if not len(f):
            continue
        first = np.searchsorted(f, f, side="left")
        slot = np.arange(len(f)) - first
        ids_a[b, f, slot] = i
        box_a[b, f, slot] = x
    return ids_a, box_a, offsets[:-1]


def _rand_boxes(rng, n, w=1242.0, h=375.0):
    x1 = rng.uniform(-20, w - 30, n)
    y1 = rng.uniform(-10, h - 30, n)
    bw = rng.uniform(10, 250, n)
    bh = rng.uniform(10, 200, n)
    return f32(np.stack([x1, y1, x1 + bw, y1 + bh], 1))


def stress_edit(res: Mapping[str, SeqResults], gt_labels: Mapping[str, object], rng: np.random.Generator,
                kinds: Sequence[str] = ("swap", "drop", "add", "dontcare", "tiny", "van", "dup", "jitter",
                                        "other"),
                strength: float = 1.0, cls_name: str = "Car") -> dict[str, SeqResults]:
    """Seeded edits of a tracker output that stress TrackEval's rules.

    res: {seq: SeqResults}; gt_labels: {seq: TrackingLabels} (ground truth, for DontCare regions
    and distractor boxes). kinds (each applied with probability-like rates scaled by ``strength``):
    ``swap`` ids swapped mid-track, ``drop`` rows removed, ``add`` random boxes (new ids), ``dontcare``
    boxes inside DontCare regions, ``tiny`` boxes 20..26 px tall (including exactly 25),
    ``van`` boxes on vans / occluded / truncated GT (copies, sometimes jittered), ``dup`` exact
    copies of boxes under a new id (ties), ``jitter`` float32 jitter around IoU 0.5, ``other``
    rows of other classes and negative ids (ignored by TrackEval). Returns a new dict; rows of each
    sequence stay sorted by frame, new rows in random positions within their frame.
    """
    out = {}
    for seq, r in res.items():
        r = SeqResults(r.frame.copy(), r.track_id.copy(), r.type.astype("<U16"), r.box.copy())
        out[seq] = _stress_sequence(r, gt_labels.get(seq), rng, kinds, strength, cls_name)
    return out


def _stress_sequence(r: SeqResults, lab, rng: np.random.Generator, kinds: Sequence[str], strength: float,
                     cls_name: str) -> SeqResults:
    """:func:`stress_edit` of one sequence's rows ``r`` (a copy, edited in place), ``lab`` its
    labels or None: the edits in a fixed order (each seed one output), added rows shuffled in."""
    adds = _Additions(int(r.track_id.max()) + 1000 if len(r) else 1000, cls_name)
    n = len(r)
    if "swap" in kinds and n:
        _swap_ids(r, rng, strength)
    if "jitter" in kinds and n:
        _jitter_boxes(r, rng, strength)
    if "drop" in kinds and n:
        r = _drop_rows(r, rng, strength)
    frames_all = np.arange(int(lab.frame.max()) + 1) if lab is not None and lab.frame.size else np.arange(1)
    if "add" in kinds:
        _add_random(adds, rng, strength, frames_all)
    if "dontcare" in kinds and lab is not None:
        _add_dontcare(adds, rng, strength, lab)
    if "tiny" in kinds:
        _add_tiny(adds, rng, strength, frames_all, lab)
    if "van" in kinds and lab is not None:
        _add_distractors(adds, rng, strength, lab)
    if "dup" in kinds and len(r):
        _add_duplicates(adds, rng, strength, r)
    if "other" in kinds and len(r):
        _add_other(adds, rng, r)
    if adds.rows:
        allr = SeqResults.concat([r] + adds.rows)
        # random order within frames, then stable by frame
        perm = rng.permutation(len(allr))
        allr = allr.take(perm)
        r = allr.sorted()
    return r


class _Additions:
    """Rows added to one sequence: new ids from ``nxt`` on, of class ``cls_name`` unless given."""

    def __init__(self, nxt: int, cls_name: str):
        self.nxt, self.cls_name = nxt, cls_name
        self.rows: list[SeqResults] = []

    def new_id(self) -> int:
        self.nxt += 1
        return self.nxt - 1

    def add(self, fr, bx, ids=None, types=None) -> None:
        m = len(fr)
        if m == 0:
            return
        if ids is None:
            ids = np.arange(self.nxt, self.nxt + m)
            self.nxt += m
        if types is None:
            types = np.full(m, self.cls_name, dtype="<U16")
        self.rows.append(SeqResults(np.asarray(fr, np.int64), np.asarray(ids, np.int64), np.asarray(types, "<U16"),
                                    f32(bx)))


def _ordered(bx: np.ndarray) -> np.ndarray:
    """Boxes with their corners in order (x1 <= x2, y1 <= y2)."""
    return np.stack([np.minimum(bx[:, 0], bx[:, 2]), np.minimum(bx[:, 1], bx[:, 3]),
                     np.maximum(bx[:, 0], bx[:, 2]), np.maximum(bx[:, 1], bx[:, 3])], 1)


def _swap_ids(r: SeqResults, rng, strength: float) -> None:
    """``swap``: ids of two tracks swapped from a random frame on, a few times."""
    ids = np.unique(r.track_id)
    for _ in range(int(rng.integers(1, 4 + 6 * strength))):
        if len(ids) < 2:
            break
        a, b = rng.choice(ids, 2, replace=False)
        t0 = int(rng.integers(r.frame.min(), r.frame.max() + 1))
        late = r.frame >= t0
        ma, mb = late & (r.track_id == a), late & (r.track_id == b)
        r.track_id[ma], r.track_id[mb] = b, a


def _jitter_boxes(r: SeqResults, rng, strength: float) -> None:
    """``jitter``: float32 jitter of some boxes at a few scales (around IoU 0.5)."""
    sel = rng.random(len(r)) < 0.15 * strength
    scale = rng.choice([0.5, 2.0, 8.0, 20.0], sel.sum())[:, None]
    r.box[sel] = f32(r.box[sel] + rng.normal(0, 1, (sel.sum(), 4)) * scale)
    r.box[sel] = _ordered(r.box[sel])


def _drop_rows(r: SeqResults, rng, strength: float) -> SeqResults:
    """``drop``: rows removed, and whole stretches of a few tracks (fragmentation)."""
    keep = rng.random(len(r)) >= 0.1 * strength
    for tid in rng.choice(np.unique(r.track_id), min(3, len(np.unique(r.track_id))), replace=False):
        t0 = int(rng.integers(r.frame.min(), r.frame.max() + 1))
        keep &= ~((r.track_id == tid) & (r.frame >= t0) & (r.frame < t0 + int(rng.integers(1, 15))))
    return r.take(np.flatnonzero(keep))


def _add_random(adds: _Additions, rng, strength: float, frames_all: np.ndarray) -> None:
    """``add``: random boxes with new ids, and one short track (the same id over consecutive frames)."""
    m = int(rng.integers(5, 20 + 40 * strength))
    fr = rng.choice(frames_all, m)
    adds.add(fr, _rand_boxes(rng, m))
    t0 = int(rng.choice(frames_all))
    L_ = int(rng.integers(3, 12))
    fr2 = np.arange(t0, min(t0 + L_, frames_all[-1] + 1))
    adds.add(fr2, np.repeat(_rand_boxes(rng, 1), len(fr2), 0), ids=np.full(len(fr2), adds.new_id()))


def _add_dontcare(adds: _Additions, rng, strength: float, lab) -> None:
    """``dontcare``: boxes in DontCare regions: mostly inside (IoA > 0.5), some half outside (IoA
    ~ 0.5), some covering, and three exactly the region."""
    dc = np.flatnonzero(np.char.lower(lab.type.astype(str)) == "dontcare")
    if not dc.size:
        return
    pick = rng.choice(dc, min(dc.size, int(10 + 30 * strength)), replace=False)
    b = lab.box[pick]
    w, h = b[:, 2] - b[:, 0], b[:, 3] - b[:, 1]
    fx = rng.uniform(-0.6, 0.4, len(pick))
    nb = np.stack([b[:, 0] + fx * w, b[:, 1] + 0.1 * h, b[:, 0] + (fx + 1.0) * w, b[:, 3] - 0.1 * h], 1)
    nb[:, 3] = np.maximum(nb[:, 3], nb[:, 1] + rng.choice([10.0, 25.0, 30.0, 60.0], len(pick)))
    adds.add(lab.frame[pick], nb)
    adds.add(lab.frame[pick[:3]], b[:3])  # exactly the region


def _add_tiny(adds: _Additions, rng, strength: float, frames_all: np.ndarray, lab) -> None:
    """``tiny``: boxes 20..26 px tall (exactly 25 among them), and on small ground-truth objects."""
    m = int(rng.integers(5, 10 + 20 * strength))
    fr = rng.choice(frames_all, m)
    bx = _rand_boxes(rng, m)
    hts = rng.choice([20.0, 24.5, 25.0, 25.0000001, 26.0], m)
    y1 = np.round(bx[:, 1])
    bx[:, 1], bx[:, 3] = y1, y1 + hts
    adds.add(fr, bx)
    if lab is not None:
        small = np.flatnonzero((lab.box[:, 3] - lab.box[:, 1] < 40) & (lab.track_id >= 0))
        if small.size:
            pick = rng.choice(small, min(small.size, 10), replace=False)
            adds.add(lab.frame[pick], lab.box[pick])


def _add_distractors(adds: _Additions, rng, strength: float, lab) -> None:
    """``van``: copies (half of them jittered) of vans, persons, occluded or truncated ground truth."""
    t = np.char.lower(lab.type.astype(str))
    distract = np.flatnonzero(((t == "van") | (t == "person") | (lab.occluded > 2) | (lab.truncated > 0))
                              & (t != "dontcare"))
    if distract.size:
        pick = rng.choice(distract, min(distract.size, int(10 + 40 * strength)), replace=False)
        bx = lab.box[pick] + rng.normal(0, 2.0, (len(pick), 4)) * (rng.random((len(pick), 1)) < 0.5)
        adds.add(lab.frame[pick], _ordered(bx))


def _add_duplicates(adds: _Additions, rng, strength: float, r: SeqResults) -> None:
    """``dup``: exact copies of boxes under new ids, and a duplicated track segment (ties in HOTA's
    assignment)."""
    pick = rng.choice(len(r), min(len(r), int(5 + 20 * strength)), replace=False)
    adds.add(r.frame[pick], r.box[pick])
    tid = int(rng.choice(np.unique(r.track_id)))
    seg = np.flatnonzero(r.track_id == tid)[:20]
    adds.add(r.frame[seg], r.box[seg], ids=np.full(len(seg), adds.new_id()))


def _add_other(adds: _Additions, rng, r: SeqResults) -> None:
    """``other``: copies of rows as other classes, and with negative ids (both ignored by TrackEval)."""
    pick = rng.choice(len(r), min(len(r), 10), replace=False)
    adds.add(r.frame[pick], r.box[pick], types=rng.choice(["Pedestrian", "Cyclist", "Van", "DontCare"], len(pick)))
    pick = rng.choice(len(r), min(len(r), 5), replace=False)
    adds.add(r.frame[pick], r.box[pick], ids=-np.ones(len(pick), np.int64))


def naive_tracks(frame: np.ndarray, box: np.ndarray, iou_min: float = 0.3) -> np.ndarray:
    """Greedy frame-to-frame IoU linking of detections (frame-sorted) -> [R] int64 track ids."""
    ids = np.full(len(frame), -1, dtype=np.int64)
    nxt = 0
    prev_idx = np.zeros(0, dtype=np.int64)
    for f in np.unique(frame):
        cur = np.flatnonzero(frame == f)
        if prev_idx.size and cur.size:
            a = np.repeat(prev_idx, cur.size)
            b = np.tile(cur, prev_idx.size)
            iou = pair_iou(box[a], box[b]).reshape(prev_idx.size, cur.size)
            used_p, used_c = set(), set()
            for flat in np.argsort(-iou, axis=None):
                i, j = divmod(int(flat), cur.size)
                if iou[i, j] < iou_min:
                    break
                if i in used_p or j in used_c:
                    continue
                used_p.add(i)
                used_c.add(j)
                ids[cur[j]] = ids[prev_idx[i]]
        for j in cur:
            if ids[j] < 0:
                ids[j] = nxt
                nxt += 1
        prev_idx = cur
    return ids

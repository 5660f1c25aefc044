"""The padded output as AB3DMOT's result files (``results/KITTI/<det>_<Cat>_val_H1/data_0/SSSS.txt``):
one line per written track and frame, newest track first, ``save_results``' format
``frame id type 0 0 alpha x1 y1 x2 y2 h w l x y z rot_y score`` (``%d %d %s`` then ``%f``).

Ids: AB3DMOT's one counter, from 1 in the first sequence, running on across sequences (every
birth takes one, written or not). Each sequence's ids are renumbered from the counter's value at
its start, so the lines are AB3DMOT's whatever counter the run started from.
"""

from __future__ import annotations


import numpy as np

from ...io.result_writer import write_sequence_files
from .data import TYPE_NAMES, Split
from .batch import RunOutput

__all__ = ["LINE_FORMAT", "result_lines", "write_results"]

LINE_FORMAT = "%d %d %s 0 0 %f %f %f %f %f %f %f %f %f %f %f %f %f"


def result_lines(split: Split, output: RunOutput, lane: int = 0, run_first_id: int = 1, first_id: int = 1,
                 starts: dict[str, int] | None = None) -> dict[str, list[str]]:
    """{sequence name: lines (no newline)} of one lane of ``output`` (``batch.run`` over ``split``'s
    frames, ids from ``run_first_id``), renumbered as AB3DMOT's counter from ``first_id`` (or from
    ``starts[name]`` at the start of a sequence named there)."""
    ids, src, boxes, next_id = (np.asarray(a[lane]) for a in (output.ids, output.src, output.boxes, output.next_id))
    if boxes.shape[-1] != 7:
        raise ValueError("the output holds no 3D boxes (run with Options(boxes=True))")
    info = split.info.reshape(-1, 7)
    out: dict[str, list[str]] = {name: [] for name in split.names}
    bounds = list(np.flatnonzero(split.frames.reset)) + [len(ids)]
    counter = first_id
    for t0, t1 in zip(bounds[:-1], bounds[1:]):
        start = int(next_id[t0 - 1]) if t0 > 0 else run_first_id     # the run's counter at the sequence's start
        counter = (starts or {}).get(split.names[split.sequence[t0]], counter)
        shift = counter - start
        lines = out[split.names[split.sequence[t0]]]
        for t in range(t0, t1):
            frame = int(split.frame[t])
            for slot in np.flatnonzero(ids[t] >= 0)[::-1]:
                alpha, kind, x1, y1, x2, y2, score = info[int(src[t, slot])]
                x, y, z, th, l, w, h = boxes[t, slot]
                lines.append(LINE_FORMAT % (frame, int(ids[t, slot]) + shift, TYPE_NAMES[int(kind)], alpha,
                                            x1, y1, x2, y2, h, w, l, x, y, z, th, score))
        counter += int(next_id[t1 - 1]) - start
    return out


def write_results(lines: dict[str, list[str]], folder) -> None:
    """``folder/SSSS.txt`` per sequence, one line each, every line ending with a newline
    (:func:`dfrmot_jax.io.result_writer.write_sequence_files`)."""
    write_sequence_files(folder, lines)

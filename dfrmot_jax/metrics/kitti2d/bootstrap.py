"""Paired bootstrap over sequences of two outputs' TrackEval figures, exact per resample.

A resample draws S sequences with replacement (the same draw for both outputs: paired) and combines
them as TrackEval combines sequences (:func:`~dfrmot_jax.metrics.kitti2d.evaluate.combine_sequences`:
sums of the per-sequence counts, HOTA's per-alpha sums, weighted averages), from the per-sequence
fields already computed: no output is scored again. A resample's figures therefore equal scoring the
resampled set of result files directly, a sequence drawn twice counting twice (tested). Written here
because no well-kept library does it: ``scipy.stats.bootstrap`` resamples observations of a statistic
that is a function of those observations alone, while a combined HOTA is a ratio of sums over
sequences with weights (its pairs' statistic would need every resample's S sequences anyway); this
is that loop, vectorised over resamples.

:func:`seq_fields` gives an output's per-sequence fields; :func:`paired_bootstrap` the figures of
both outputs on ``n`` resamples; :func:`intervals` the percentile interval of B - A and the share of
resamples where B is better (lower for the counts to minimise: FP, FN, IDSW, Frag).
"""

from __future__ import annotations

from typing import Mapping, Sequence

import numpy as np

from . import hota
from .evaluate import RAW_FIELDS, batch_fields, combine_sequences, summary_columns
from .kitti import preprocess

__all__ = ["BOOTSTRAP_FIELDS", "LOWER_IS_BETTER", "TP_WEIGHTED_FIELDS", "seq_fields", "batch_seq_fields", "resample_indices", "counts_of",
           "paired_bootstrap", "intervals", "resample_combined", "resampled_figure"]

#: the summary fields a comparison reports (``dfrmot eval``'s names: HOTA family in percent, CLEAR's counts)
BOOTSTRAP_FIELDS = ("HOTA", "DetA", "AssA", "LocA", "DetRe", "DetPr", "AssRe", "AssPr", "MOTA", "IDF1", "IDSW",
                    "CLR_FP", "CLR_FN", "Frag")
#: fields where a smaller value is better
LOWER_IS_BETTER = frozenset({"IDSW", "CLR_FP", "CLR_FN", "Frag"})
#: resamples combined per vectorised step (memory: ~ this x S x 19 x 8 bytes per per-alpha field)
RESAMPLES_PER_STEP = 512


def seq_fields(gt, dets, similarity: str = "2d") -> dict[str, np.ndarray]:
    """The per-sequence TrackEval fields of one output: ``{field: [S(, 19)]}`` (the sums TrackEval
    combines, :func:`~dfrmot_jax.metrics.kitti2d.evaluate.evaluate_batch`'s ``seq`` of lane 0)."""
    return batch_seq_fields(preprocess(gt, dets, similarity))


def batch_seq_fields(b) -> dict[str, np.ndarray]:
    """:func:`seq_fields` of an output already preprocessed (an ``EvalBatch`` of one lane)."""
    out = batch_fields(b)["seq"]
    return {f: np.asarray(v)[0] for f, v in out.items()}


def resample_indices(n_seqs: int, n: int, seed: int = 0) -> np.ndarray:
    """[n, S] int64 sequence indices, each row a draw of S sequences with replacement (seeded)."""
    rng = np.random.default_rng(seed)
    return rng.integers(0, n_seqs, size=(n, n_seqs), dtype=np.int64)


def _combined(fields: Mapping[str, np.ndarray], idx: np.ndarray) -> dict[str, np.ndarray]:
    """The summary figures of the resamples ``idx`` [R, S]: {field: [R]}."""
    taken = {f: np.asarray(v)[idx] for f, v in fields.items()}        # [R, S(, 19)]
    summary = summary_columns(combine_sequences(taken))
    return {f: np.asarray(summary[f], np.float64) for f in BOOTSTRAP_FIELDS}


def paired_bootstrap(a: Mapping[str, np.ndarray], b: Mapping[str, np.ndarray], n: int = 10_000, seed: int = 0,
                     idx: np.ndarray | None = None) -> tuple[dict, dict, np.ndarray]:
    """Figures of outputs A and B (per-sequence fields, :func:`seq_fields`, on the same sequences) on
    ``n`` paired resamples: ({field: [n]} of A, of B, the resamples' indices [n, S]). ``idx``: the
    resamples to use instead of drawing them (``resample_indices``)."""
    s = next(iter(a.values())).shape[0]
    if next(iter(b.values())).shape[0] != s:
        raise ValueError("A and B must be scored on the same sequences")
    idx = resample_indices(s, n, seed) if idx is None else np.asarray(idx, np.int64)
    out_a = {f: np.empty(len(idx)) for f in BOOTSTRAP_FIELDS}
    out_b = {f: np.empty(len(idx)) for f in BOOTSTRAP_FIELDS}
    for start in range(0, len(idx), RESAMPLES_PER_STEP):
        part = idx[start:start + RESAMPLES_PER_STEP]
        for fields, out in ((a, out_a), (b, out_b)):
            for f, v in _combined(fields, part).items():
                out[f][start:start + len(part)] = v
    return out_a, out_b, idx


def intervals(boot_a: Mapping[str, np.ndarray], boot_b: Mapping[str, np.ndarray], level: float = 0.95,
              fields: Sequence[str] = BOOTSTRAP_FIELDS) -> dict[str, dict[str, float]]:
    """Per field: the percentile interval (``level``) of B - A over the resamples (``ci_low``,
    ``ci_high``) and ``p_b_better``, the share of resamples where B is better than A (ties count
    half)."""
    lo_q, hi_q = (1 - level) / 2, 1 - (1 - level) / 2
    out = {}
    for f in fields:
        d = np.asarray(boot_b[f]) - np.asarray(boot_a[f])
        better = -d if f in LOWER_IS_BETTER else d
        out[f] = {"ci_low": float(np.quantile(d, lo_q)), "ci_high": float(np.quantile(d, hi_q)),
                  "p_b_better": float(np.mean(better > 0) + 0.5 * np.mean(better == 0))}
    return out


#: fields TrackEval combines as averages weighted by ``HOTA_TP`` (``hota.hota_combine``); every other
#: per-sequence field is a plain sum over sequences
TP_WEIGHTED_FIELDS = ("AssRe", "AssPr", "AssA", "LocA")


def resample_combined(arrays: Mapping[str, np.ndarray], counts: np.ndarray) -> dict[str, np.ndarray]:
    """The combined fields of C configs on R resamples given as multiplicities: ``arrays`` {field:
    [C, S(, 19)]} (a sweep's per-sequence fields), ``counts`` [R, S] (how often each sequence is drawn)
    -> {field: [C * R(, 19)]}, config-major (config c, resample r at ``c * R + r``).

    Each resample's sums are matrix products with its counts (no [C, R, S] array is made): the
    summed fields directly, the ``HOTA_TP``-weighted averages as their weighted sums over the summed
    weight; the result is handed to :func:`~dfrmot_jax.metrics.kitti2d.evaluate.combine_sequences` as
    one pseudo-sequence, so every derived field is TrackEval's formula (``hota.hota_combine`` alone when
    ``arrays`` holds HOTA's sums only, ``RAW_FIELDS``). Equal to combining the drawn
    sequences one by one up to rounding (tested to 1e-9): for the reports' intervals over many
    configs, where :func:`paired_bootstrap`'s exact path would need [C, R, S] arrays."""
    w = np.asarray(counts, np.float64)
    tp = np.asarray(arrays["HOTA_TP"], np.float64)

    def summed(v):                       # [C, S, ...] x [R, S] -> [C, R, ...]
        return np.moveaxis(np.tensordot(np.asarray(v, np.float64), w, axes=([1], [1])), -1, 1)

    tp_sum = summed(tp)
    out = {}
    for f, v in arrays.items():
        if f in TP_WEIGHTED_FIELDS:
            num = summed(np.asarray(v, np.float64) * tp)
            with np.errstate(invalid="ignore", divide="ignore"):
                out[f] = np.where(tp_sum > 0, num / np.where(tp_sum > 0, tp_sum, 1.0), 0.0)
        else:
            out[f] = summed(v)
    c, r = tp_sum.shape[:2]
    one = {f: v.reshape((c * r, 1) + v.shape[2:]) for f, v in out.items()}
    return hota.hota_combine(one) if set(one) == set(RAW_FIELDS) else combine_sequences(one)


def resampled_figure(arrays: Mapping[str, np.ndarray], counts: np.ndarray, field: str,
                     per_step: int = 128) -> np.ndarray:
    """One summary field (``dfrmot eval``'s units) of C configs on R resamples -> [C, R]
    (:func:`resample_combined`, ``per_step`` resamples at a time)."""
    if field in hota.FLOAT_ARRAY_FIELDS + hota.FLOAT_FIELDS:          # HOTA's family needs its sums only
        arrays = {f: arrays[f] for f in RAW_FIELDS}
    c = next(iter(arrays.values())).shape[0]
    out = np.empty((c, len(counts)))
    for start in range(0, len(counts), per_step):
        part = counts[start:start + per_step]
        out[:, start:start + len(part)] = summary_columns(resample_combined(arrays, part))[field].reshape(c, len(part))
    return out


def counts_of(idx: np.ndarray, n_seqs: int) -> np.ndarray:
    """Resamples as sequence indices [R, S] -> multiplicities [R, S]."""
    r = np.repeat(np.arange(len(idx)), idx.shape[1])
    out = np.zeros((len(idx), n_seqs), np.int64)
    np.add.at(out, (r, idx.reshape(-1)), 1)
    return out

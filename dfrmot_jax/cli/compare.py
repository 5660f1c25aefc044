"""``dfrmot compare A B``: two result folders compared on the same sequences, with paired bootstrap
intervals over sequences (:mod:`dfrmot_jax.report.compare`).

Usage: ``dfrmot compare A B [--data ROOT] [--class car[,pedestrian]] [--seqs 0000,0002 | --seqmap FILE]
[--resamples 10000] [--seed 0] [--metrics kitti2d,ab3dmot] [--ab3dmot-sum compensated|sequential]
[--recall-table F] [--csv OUT.csv] [--html OUT.html] [--allow-missing]``. A and B are read and checked as
``dfrmot eval`` reads them (the same refusals, exit 2). Prints, per class, the COMBINED figures of A and
B, B - A with its 95 % interval and the share of resamples where B is better, and the sequences where
HOTA moves most; ``--csv`` writes the tidy table (one row per class, sequence or ``COMBINED``, metric:
``class seq metric a b diff ci_low ci_high p_b_better resamples``); ``--html`` one self-contained page
with the ground-truth tracks treated most differently, their timelines and bird's-eye views
(:mod:`dfrmot_jax.report.compare_html`). With AB3DMOT's figures (``--metrics ab3dmot``), the sum of
track scores is ``--ab3dmot-sum``'s (the other sum's figures in a line where they differ), and
``--recall-table`` writes both outputs' recall points (also on the page).
"""

from __future__ import annotations

import tempfile

import pandas as pd
from pathlib import Path

from ..io.kitti import KittiFormatError
from ..report.stored import read_manifest
from ..sweep.config_output import class_data, sweep_classes, write_config_output
from ..metrics.kitti2d.tracker_files import read_tracker_files
from ..report.compare import compare_outputs, comparison_text
from ..metrics.samota.table import other_sum_line, recall_table
from ..report.compare_samota import ab3dmot_rows
from ..report.compare_html import write_compare_html
from .args import ab3dmot_settings, check_output_files
from .eval import check_class_rows, check_folders, chosen_sequences, ground_truth, label_root

__all__ = ["run", "parse_reference", "check_outputs", "check_reference"]


def parse_reference(text: str) -> tuple[Path, str | int] | None:
    """``DIR:best`` | ``DIR:baseline`` | ``DIR:config=N`` -> (DIR, 'best' | 'baseline' | N); None when
    ``text`` is no such reference (an existing folder is always a folder)."""
    if Path(text).is_dir() or ":" not in text:
        return None
    head, _, which = text.rpartition(":")
    if not (Path(head) / "manifest.json").is_file():
        raise ValueError(f"{text}: not a folder, nor a sweep or tune directory's config ({head} has no manifest.json)")
    if which in ("best", "baseline"):
        return Path(head), which
    if which.startswith("config="):
        try:
            return Path(head), int(which.removeprefix("config="))
        except ValueError:
            raise ValueError(f"{text}: expected DIR:config=N with N a config number") from None
    raise ValueError(f"{text}: expected DIR:best, DIR:baseline or DIR:config=N")


def check_outputs(csv: str | None, html: str | None) -> None:
    """Refuse (ValueError) ``--csv`` and ``--html`` naming one file: the page would replace the table."""
    if csv and html and Path(csv).resolve() == Path(html).resolve():
        raise ValueError(f"--csv {csv} and --html {html} name one file: the page would replace the table; "
                         f"give each its own")


def scoring_root(data, refs, manifests, classes) -> str | None:
    """The KITTI root both sides are scored against: a ``DIR:`` side's own data root (the ground
    truth its configs were tracked and scored on), else ``--data`` (``data``; None: the default).
    Two sides tracked on different roots, or ``--data`` naming another, are refused naming both."""
    tracked = []
    for ref, manifest in zip(refs, manifests):
        if ref is not None:
            cls = next((c for c in classes if c in sweep_classes(manifest)), sweep_classes(manifest)[0])
            tracked.append((ref[0], class_data(manifest, cls)["root"]))
    for (d1, r1), (d2, r2) in zip(tracked, tracked[1:]):
        if Path(r1).resolve() != Path(r2).resolve():
            raise ValueError(f"{d1} was tracked on {r1}, {d2} on {r2}: two sides on different data cannot be "
                             f"compared")
    if not tracked:
        return data
    d, r = tracked[0]
    if data is not None and Path(data).resolve() != Path(r).resolve():
        raise ValueError(f"--data {data}, but {d} was tracked on {r}: a directory's config is scored against its "
                         f"own data's ground truth (leave out --data, or compare outputs of one data root)")
    return r


def check_reference(directory: Path, manifest: dict, classes, seqs) -> None:
    """Refuse (ValueError naming ``directory``) a sweep / tune directory's config for a class it did
    not track or sequences outside its data: its result files would lack them, and the refusal would
    name a temporary folder and blame its files."""
    tracked = sweep_classes(manifest)
    missing = [c for c in classes if c not in tracked]
    if missing:
        both = ",".join(c for c in classes if c in tracked) or tracked[0]
        raise ValueError(f"{directory}: the directory tracked {', '.join(tracked)} only, not {', '.join(missing)} "
                         f"(--class {','.join(classes)}): compare --class {both}, or a directory that tracked "
                         f"{', '.join(missing)}")
    held = {s for c in tracked for s in class_data(manifest, c)["sequences"]}
    outside = [s for s in seqs or () if s not in held]
    if outside:
        raise ValueError(f"{directory}: sequences {', '.join(outside)} are outside the directory's data (it tracked "
                         f"{', '.join(sorted(held))}): name sequences it tracked (--seqs, --seqmap)")


def run(args) -> int:
    """Run ``compare`` for parsed ``args``: 0, or raises ValueError (bad ground truth, folders, arguments)."""
    ab3dmot_settings(args)
    check_outputs(args.csv, args.html)
    check_output_files([("--csv", args.csv), ("--html", args.html), ("--recall-table", args.recall_table)],
                       [("--seqmap", args.seqmap)], [("A", args.a), ("B", args.b)])
    refs = [parse_reference(str(x)) for x in (args.a, args.b)]
    manifests = [None if r is None else read_manifest(r[0]) for r in refs]
    root, label_dir = label_root(scoring_root(args.data, refs, manifests, args.cls))
    sweep_seqs = next((m["data"]["sequences"] for m in manifests if m is not None), None)
    seqs = chosen_sequences(args.seqs, args.seqmap, root, sweep_seqs)
    for ref, manifest in zip(refs, manifests):
        if ref is not None:
            check_reference(ref[0], manifest, args.cls, seqs)
    gts, seq_lists = ground_truth(root, args.cls, seqs, True)
    with tempfile.TemporaryDirectory(prefix="dfrmot-compare-") as tmp:
        names = [str(args.a), str(args.b)]
        folders = [Path(args.a), Path(args.b)]
        for i, ref in enumerate(refs):
            if ref is not None:                   # a sweep's config: tracked alone, written here
                folders[i] = Path(tmp) / "AB"[i]
                names[i] = write_config_output(ref[0], ref[1], folders[i])
        return _compare(args, root, label_dir, seqs, gts, seq_lists, folders, names)


def _compare(args, root: Path, label_dir: Path, seqs, gts: dict, seq_lists: dict, folders: list, names: list) -> int:
    """The comparison of two result folders (``names``: how to call them)."""
    check_folders(folders, label_dir, seq_lists, seqs, args.allow_missing)
    dets = []
    for d in folders:
        per_class = {c: _read(d, gt, bool(args.html)) for c, gt in gts.items()}
        for c, gt in gts.items():
            check_class_rows(d, c, seq_lists[c], int(gt.n_gt_dets.sum()), per_class[c].frame.size,
                             args.allow_missing, "compare")
        dets.append(per_class)
    result = compare_outputs(gts, dets[0], dets[1], names[0], names[1], args.resamples, args.seed)
    print(comparison_text(result))
    if "ab3dmot" in args.metrics or args.recall_table:
        _ab3dmot(args, root, seq_lists, folders, result)
    if args.csv:
        out = Path(args.csv)
        out.parent.mkdir(parents=True, exist_ok=True)
        result.table.to_csv(out, index=False)
        print(f"wrote {out}")
    if args.html:
        write_compare_html(result, args.html)
        print(f"wrote {args.html}")
    return 0


def _ab3dmot(args, root: Path, seq_lists: dict, folders: list, result) -> None:
    """AB3DMOT's figures with their intervals: printed, and added to ``result.table``'s COMBINED rows."""
    rows, recalls = [], []
    result.ab3dmot = {}
    for cls, seqs in seq_lists.items():
        got, per, points = ab3dmot_rows(root, cls, list(seqs), folders[0], folders[1], args.ab3dmot_resamples,
                                        args.seed, args.ab3dmot_iou, sum_mode=args.ab3dmot_sum, progress=True)
        rows += got
        result.ab3dmot[cls] = tuple(points)
        recalls += [recall_table(r, tracker=k, **{"class": cls}) for k, r in zip("AB", points)]
        print(f"\n{cls}, AB3DMOT (IoU {args.ab3dmot_iou}, {args.ab3dmot_sum} sum): {args.ab3dmot_resamples:,} paired "
              f"resamples, each rescored ({per:.2f} s per resample)")
        for r in got:
            count = r["metric"].split("@")[0] in ("ab3dmot_IDS", "ab3dmot_FP", "ab3dmot_FN")
            f = (lambda v: f"{int(round(v)):+d}") if count else (lambda v: f"{v:+.2f}")
            g = (lambda v: f"{int(round(v))}") if count else (lambda v: f"{v:.2f}")
            print(f"{r['metric']:<22} {g(r['a']):>8} {g(r['b']):>8} {f(r['diff']):>8}   [{f(r['ci_low']):>8}, "
                  f"{f(r['ci_high']):>8}]   {r['p_b_better']:.3f}")
        for k, r in zip("AB", points):
            if (line := other_sum_line(r, k)) is not None:
                print(line)
    if args.recall_table:
        out = Path(args.recall_table)
        out.parent.mkdir(parents=True, exist_ok=True)
        pd.concat(recalls, ignore_index=True).to_csv(out, index=False)
        print(f"wrote {out}")
    result.table = pd.concat([result.table, pd.DataFrame(rows, columns=list(result.table.columns))],
                             ignore_index=True)
    result.table["resamples"] = result.table["resamples"].astype("Int64")


def _read(d: Path, gt, with_3d: bool):
    """A folder's rows of ``gt``'s class; with ``with_3d`` (the page's bird's-eye views) also their 3D
    fields, when every row's are readable (else without: the views then draw the ground truth only, and
    say so by having no rows)."""
    if with_3d:
        try:
            return read_tracker_files(d, gt, need_3d=True)
        except KittiFormatError:
            pass
    return read_tracker_files(d, gt)

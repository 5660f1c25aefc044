"""Issue 51, items 11 and 17: what the compare page and the recall-point tables show. The page says
how many resamples each row used and prints AB3DMOT's counts as whole numbers (item 11); AB3DMOT's
recall points are a plot (sMOTA and TP_ignored against the recall point, A and B, both sums, the
drift's dropped passes marked) with the table folded below it; the recall point is a percent like
every ratio of the table (7.5, not 0.07500000000000001), and eval's and compare's CSVs name the
output by one column, ``tracker`` (item 17)."""

from __future__ import annotations

import re
from pathlib import Path

import pandas as pd

from dfrmot_jax.testing.cli import run_cli

N_CAR = 40


def _drift_scene(tmp_path) -> tuple[Path, Path, Path]:
    """One car over 40 frames tracked by one track of score 1.0111 (whose sequential mean drifts), a
    van (ignored ground truth) covered by a track of score 0.5; B: the same without the van's track
    and the car's last ten frames."""
    root = tmp_path / "data"
    (root / "label_02").mkdir(parents=True)
    labels, rows = [], []
    for f in range(N_CAR):
        labels.append(f"{f} 1 Car 0 0 -1 100 150 180 220 1.5 1.6 3.9 0.0 1.7 {10 + f} 0.2")
        rows.append(f"{f} 7 Car -1 -1 -1 100 150 180 220 1.5 1.6 3.9 0.0 1.7 {10 + f} 0.2 1.0111")
        if f < 10:
            labels.append(f"{f} 2 Van 0 0 -1 400 150 480 220 1.9 1.8 4.5 6.0 1.8 20 0.2")
            rows.append(f"{f} 8 Car -1 -1 -1 400 150 480 220 1.9 1.8 4.5 6.0 1.8 20 0.2 0.5")
    (root / "label_02" / "0000.txt").write_text("\n".join(labels) + "\n")
    a, b = tmp_path / "a", tmp_path / "b"
    a.mkdir()
    b.mkdir()
    (a / "0000.txt").write_text("\n".join(rows) + "\n")
    (b / "0000.txt").write_text("\n".join(r for r in rows if " 7 Car" in r and int(r.split()[0]) < 30) + "\n")
    return root, a, b


def test_compare_page_resamples_counts_and_recall_plot(tmp_path, capsys):
    root, a, b = _drift_scene(tmp_path)
    page, points = tmp_path / "c.html", tmp_path / "c.csv"
    status, out, err = run_cli(capsys, ["compare", a, b, "--data", root, "--metrics", "kitti2d,ab3dmot",
                                        "--ab3dmot-iou", "2d:0.5", "--ab3dmot-resamples", "3", "--resamples", "50",
                                        "--html", page, "--recall-table", points])
    assert status == 0, err
    html = page.read_text()
    lead = re.search(r'<p class="lead">(.*?)</p>', html, re.S).group(1)
    assert "50 resamples" in lead and "3 resamples" in lead           # each row's count, not 50 for all
    cells = re.findall(r"<tr><td>(ab3dmot_(?:IDS|FP|FN|FRAG)@[^<]*)</td>((?:<td>[^<]*</td>)+)</tr>", html)
    assert cells
    for _, row in cells:
        a_, b_, diff, lo, hi = re.findall(r"<td>([^<]*)</td>", row)[:5]
        assert all(re.fullmatch(r"[+-]?\d+", v) for v in (a_, b_, diff, lo, hi)), row
    section = html[html.index("AB3DMOT's recall points"):]
    assert "<svg" in section.split("<details>")[0]                    # the plot first
    assert "<details>" in section and "TP_ignored" in section        # the table folded below it
    t = pd.read_csv(points)
    assert "tracker" in t.columns and "output" not in t.columns and set(t["tracker"]) == {"A", "B"}
    assert set(t["sum"]) == {"compensated", "sequential"}
    assert 7.5 in set(t["recall_point"]) and t["recall_point"].max() == 100.0
    assert "0.07500000000000001" not in points.read_text()


def test_eval_recall_table_shares_compares_columns(tmp_path, capsys):
    root, a, _ = _drift_scene(tmp_path)
    f = tmp_path / "e.csv"
    status, _, err = run_cli(capsys, ["eval", a, "--data", root, "--ab3dmot-iou", "2d:0.5", "--recall-table", f])
    assert status == 0, err
    t = pd.read_csv(f)
    assert list(t.columns[:3]) == ["tracker", "class", "sum"]
    assert set(t["recall_point"]) >= {2.5, 7.5, 100.0} and "0.07500000000000001" not in f.read_text()
    assert t["recall"].max() <= 100.0 and t["recall_point"].min() >= 2.5 - 1e-9

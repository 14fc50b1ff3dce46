"""experiments/basin_map.py --quick: the bracket of the throwing unbalance is consistent with its runs."""

import csv
import json

from gfb_experiments import basin_map


def test_basin_map_quick(tmp_path):
    assert basin_map.main(["--quick", "--out", str(tmp_path)]) == 0
    rows = list(csv.DictReader((tmp_path / "basin_map.csv").open()))
    runs = list(csv.DictReader((tmp_path / "runs.csv").open()))
    assert len(rows) == 1
    lo, hi = float(rows[0]["stays_below"]), float(rows[0]["thrown_above"])
    assert lo < float(rows[0]["threshold_unbalance"]) < hi <= 2.0 * lo  # the quick bracket ratio
    # monotone: every run below the bracket stayed, every run at or above it was thrown
    for r in runs:
        u, was_thrown = float(r["unbalance"]), r["thrown"] == "True"
        assert was_thrown == (u >= hi), r
    s = json.loads((tmp_path / "summary.json").read_text())
    assert s["fold_bearing_number"] < s["points"][0]["bearing_number"] < s["critical_bearing_number"]
    assert (tmp_path / "basin_map.png").stat().st_size > 10_000

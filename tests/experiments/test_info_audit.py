"""``python -m gfb_experiments.info_audit`` (issue 19 s.1): the report of what the v1 info leaks."""

from __future__ import annotations

import json

import pytest

from gfb_experiments.info_audit import main


def test_the_audit_writes_the_leak_tables_and_finds_no_contract_violation(tmp_path, capsys):
    out = tmp_path / "audit"
    assert main(["--seeds", "1", "--max-steps", "3", "--out", str(out)]) == 0
    report = json.loads((out / "v1.json").read_text())
    md = (out / "v1.md").read_text()
    assert set(report) == {"gfb_env/RunUp-v1", "gfb_env/RunUpRandomized-v1", "gfb_env/WhirlRecovery-v1"}
    for env_id, r in report.items():
        assert r["unclassified"] == [] and r["sensor_or_public_equal_to_a_hidden_parameter"] == []
        assert (
            "damping_gain" in r["ground_truth_leaks"] and "damping_gain" in r["equal_to_a_hidden_parameter"]
        )
        assert f"## {env_id}" in md and "| `damping_gain` |" in md
    assert "clearance_um" in report["gfb_env/RunUpRandomized-v1"]["equal_to_a_hidden_parameter"]
    printed = capsys.readouterr().out
    assert "## gfb_env/RunUp-v1" in printed and "## gfb_env/RunUp-v2" in printed
    # the v2 ids: no ground truth, nothing equal to a hidden draw, every key listed
    v2 = json.loads((out / "v2.json").read_text())
    assert set(v2) == {"gfb_env/RunUp-v2", "gfb_env/RunUpRandomized-v2", "gfb_env/WhirlRecovery-v2"}
    for r in v2.values():
        assert r["ground_truth_leaks"] == [] and r["equal_to_a_hidden_parameter"] == []
        assert r["unclassified"] == [] and r["verdict_before_the_final_step"] == []
        assert {"monitor", "probe_samples", "reward_whirl", "cost"} <= set(r["keys"])
    assert "**0 GROUND_TRUTH**" in (out / "v2.md").read_text()


def test_a_bad_out_is_refused_in_one_line_before_any_work(tmp_path, capsys):
    f = tmp_path / "file"
    f.write_text("x")
    with pytest.raises(SystemExit) as exc:
        main(["--out", str(f)])
    assert exc.value.code == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "--out" in err[0] and "not a folder" in err[0]

"""``python -m gfb_experiments.bench_env --against OLD_CHECKOUT`` (issue 20's yardstick): refusals up front,
and (slow) one alternating round against this very checkout gives every key with finite rates."""

import json
import math
import subprocess
import sys
from pathlib import Path

import pytest

from gfb_experiments import bench_against

REPO = Path(__file__).resolve().parents[2]


def test_against_refuses_a_folder_that_is_no_checkout(tmp_path):
    r = subprocess.run(
        [
            sys.executable,
            "-m",
            "gfb_experiments.bench_env",
            "--against",
            str(tmp_path),
            "--out",
            str(tmp_path),
        ],
        capture_output=True,
        text=True,
        timeout=60,
    )
    lines = r.stderr.strip().splitlines()
    assert r.returncode == 2 and len(lines) == 1 and "not a gfb-env checkout" in lines[0], r.stderr


def test_the_children_import_each_checkouts_own_code(tmp_path):
    links = bench_against._links(REPO, tmp_path)
    assert (links / "gfb_env").resolve() == (REPO / "gfb_env").resolve()
    assert (links / "gfb_agents").resolve() == (REPO / "agents").resolve()


@pytest.mark.slow
def test_one_round_against_itself(tmp_path):
    s = bench_against.against(
        REPO, REPO, rounds=1, env_steps=32, ppo_steps=2048, out=tmp_path, log=lambda _: None
    )
    for key in (
        "speedup_vs_against",
        "whirl_speedup_vs_against",
        "ppo_env_steps_per_s",
        "ppo_1m_steps_minutes",
        "independent_two_over_one",
        "two_processes_over_independent_two",
    ):
        assert math.isfinite(s[key]) and s[key] > 0, key
    assert json.loads((tmp_path / "against.json").read_text())["rounds"] == 1

"""The paper-figure scripts run in --quick mode and write their files."""

from __future__ import annotations

import csv
import importlib
import json

import pytest


def _run(name, out, *extra):
    mod = importlib.import_module(f"experiments.{name}")
    assert mod.main(["--quick", "--out", str(out), *extra]) == 0


def test_fig4_quick(tmp_path):
    _run("fig4_stability_map", tmp_path)
    rows = list(csv.DictReader((tmp_path / "stability_map.csv").open()))
    assert len(rows) == 1 + 2 + 4
    assert (tmp_path / "stability_map.png").stat().st_size > 1000
    s = json.loads((tmp_path / "summary.json").read_text())
    assert s["rigid_critical_bearing_number"] > 0


def test_fig5_quick(tmp_path):
    _run("fig5_runup", tmp_path)
    assert (tmp_path / "envelopes.csv").exists() and (tmp_path / "runup_coastdown.png").exists()
    s = json.loads((tmp_path / "summary.json").read_text())
    assert set(s["cases"]) == {"rigid", "viscoelastic"}


def test_fig6_quick(tmp_path):
    _run("fig6_limit_cycles", tmp_path)
    rows = list(csv.DictReader((tmp_path / "limit_cycles.csv").open()))
    assert rows[0]["structure"] == "elastic"
    assert (tmp_path / "limit_cycles.png").exists() and (tmp_path / "orbits.csv").exists()


def test_fig7_quick(tmp_path):
    _run("fig7_fft", tmp_path)
    assert (tmp_path / "fft.png").exists() and (tmp_path / "fft_peaks.csv").exists()


@pytest.mark.slow
def test_hysteresis_quick(tmp_path):
    _run("hysteresis_map", tmp_path)
    rows = list(csv.DictReader((tmp_path / "hysteresis_map.csv").open()))
    assert {"foil_stiffness", "foil_damping", "critical_bearing_number", "fold_bearing_number"} <= set(
        rows[0]
    )
    assert float(rows[0]["fold_bearing_number"]) < float(rows[0]["critical_bearing_number"])


def test_convergence_study_quick(tmp_path):
    _run("convergence_study", tmp_path)
    rows = list(csv.DictReader((tmp_path / "convergence.csv").open()))
    assert [r["status"] for r in rows] == ["done", "done"]
    assert float(rows[0]["relative_amplitude_error"]) < 2e-3  # rtol 1e-2 vs 1e-3 on the rigid 31x5 cycle
    assert (tmp_path / "convergence.png").stat().st_size > 1000

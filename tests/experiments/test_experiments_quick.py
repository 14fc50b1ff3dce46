"""The paper-figure scripts run in --quick mode and write their files."""

from __future__ import annotations

import csv
import importlib
import json

import pytest


def _run(name, out, *extra):
    mod = importlib.import_module(f"gfb_experiments.{name}")
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
    rigid, visco = s["cases"]["rigid"], s["cases"]["viscoelastic"]
    # the whirl sets in on the run-up, later with the damped foil (paper Fig. 5), and grows to an orbit
    # of the order of the clearance
    assert 0.5 < rigid["onset_bearing_number_runup"] < visco["onset_bearing_number_runup"] < 0.8
    for c in (rigid, visco):
        assert c["max_xi_peak_to_peak"] > 1.0 and c["max_p00"] > 1.0
    rows = list(csv.DictReader((tmp_path / "envelopes.csv").open()))
    assert {r["structure"] for r in rows} == {"rigid", "viscoelastic"}
    lam = [float(r["bearing_number"]) for r in rows if r["structure"] == "rigid" and r["leg"] == "up"]
    assert lam == sorted(lam) and lam[0] == pytest.approx(0.5, abs=0.01)  # the ramp starts at 0.5


def test_fig6_quick(tmp_path):
    _run("fig6_limit_cycles", tmp_path)
    rows = list(csv.DictReader((tmp_path / "limit_cycles.csv").open()))
    assert rows[0]["structure"] == "elastic"
    assert (tmp_path / "limit_cycles.png").exists() and (tmp_path / "orbits.csv").exists()


def test_fig7_quick(tmp_path):
    _run("fig7_fft", tmp_path)
    assert (tmp_path / "fft.png").stat().st_size > 10_000
    rows = list(csv.DictReader((tmp_path / "fft_peaks.csv").open()))
    assert [(float(r["foil_damping"]), r["status"]) for r in rows] == [(4.0, "whirl"), (16.0, "whirl")]
    for r in rows:
        # a sub-synchronous whirl (paper Fig. 7: the peak lies just below omega = Lambda / 2)
        assert 0.3 < float(r["ratio"]) < 0.55
        assert float(r["ratio"]) == pytest.approx(float(r["omega"]) / 0.6, rel=1e-12)
        assert 0 < float(r["amplitude"]) < float(r["max_eccentricity"]) < 1.5
    # near the optimum D_W = 4 the whirl is smaller than over-damped (the point of Fig. 7)
    assert float(rows[0]["amplitude"]) < float(rows[1]["amplitude"])
    spectra = list(csv.DictReader((tmp_path / "spectra.csv").open()))
    for dw, r in zip(("4.0", "16.0"), rows):
        sp = [s for s in spectra if s["foil_damping"] == dw]
        peak = max(sp, key=lambda s: float(s["amplitude"]))
        assert float(peak["omega_over_lambda"]) == pytest.approx(float(r["ratio"]), abs=0.03)
    s = json.loads((tmp_path / "summary.json").read_text())
    assert s["grid"] == "33x7" and len(s["peaks"]) == 2


@pytest.mark.slow
def test_hysteresis_quick(tmp_path):
    _run("hysteresis_map", tmp_path)
    rows = list(csv.DictReader((tmp_path / "hysteresis_map.csv").open()))
    assert {"foil_stiffness", "foil_damping", "critical_bearing_number", "fold_bearing_number"} <= set(
        rows[0]
    )
    assert float(rows[0]["fold_bearing_number"]) < float(rows[0]["critical_bearing_number"])


@pytest.mark.slow  # 8-16 s: in `make test-slow` (the default run's 10-minute budget)
def test_convergence_study_quick(tmp_path):
    _run("convergence_study", tmp_path)
    rows = list(csv.DictReader((tmp_path / "convergence.csv").open()))
    assert [r["status"] for r in rows] == ["done", "done"]
    assert float(rows[0]["relative_amplitude_error"]) < 2e-3  # rtol 1e-2 vs 1e-3 on the rigid 31x5 cycle
    assert (tmp_path / "convergence.png").stat().st_size > 1000


@pytest.mark.parametrize(
    "module",
    [
        "fig4_stability_map",
        "fig5_runup",
        "fig6_limit_cycles",
        "fig7_fft",
        "convergence_study",
        "grid_convergence",
        "hysteresis_map",
    ],
)
def test_experiment_refuses_unwritable_out_at_once(module, tmp_path, capsys):
    """An output folder that cannot be made is one line and exit 2 before any computation."""
    import time

    blocker = tmp_path / "file.txt"
    blocker.write_text("x")
    main = importlib.import_module(f"gfb_experiments.{module}").main
    t0 = time.perf_counter()
    with pytest.raises(SystemExit) as exc:
        main(["--out", str(blocker / "out")])
    out, err = capsys.readouterr()
    assert exc.value.code == 2
    assert len(err.strip().splitlines()) == 1 and "--out" in err and "is a file" in err, err
    assert time.perf_counter() - t0 < 5.0
    assert not (blocker.parent / "out").exists()

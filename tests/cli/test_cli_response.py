"""``gfb response`` and ``gfb simulate --unbalance`` (issue 10): JSON keys, the transient check, units,
and one-line refusals."""

import csv
import json

import pytest
from conftest import assert_refused_at_once

from gfb_env.analysis.response import unbalance_response
from gfb_env.cli import main
from gfb_env.forcing import Unbalance
from gfb_env.model import GFBModel
from gfb_env.params import BearingParameters


def run(capsys, *argv):
    code = main([str(a) for a in argv])
    out, err = capsys.readouterr()
    return code, out, err


@pytest.mark.slow  # 8-16 s: in `make test-slow` (the default run's 10-minute budget)
def test_response_json_keys_at_a_speed_and_verify(tmp_path, capsys):
    code, out, err = run(
        capsys, "response", "--structure", "rigid", "--grid", "31x7", "--unbalance", "0.01",
        "--bearing-number", "0.3", "--bearing-range", "0.1", "0.7", "--n-speeds", "7", "--verify",
        "--out", tmp_path, "--json",
    )  # fmt: skip
    assert code == 0, err
    d = json.loads(out)
    want = unbalance_response(GFBModel("rigid", grid="31x7"), 0.3, 0.01)
    assert d["xi_amplitude"] == pytest.approx(want.xi_amplitude, rel=1e-9)
    assert d["eta_amplitude"] == pytest.approx(want.eta_amplitude, rel=1e-9)
    assert d["semi_major"] >= d["semi_minor"] > 0 and isinstance(d["forward"], bool)
    assert d["verify"]["xi_relative_error"] < 0.02 and d["verify"]["eta_relative_error"] < 0.02
    assert d["eta_amplitude_um"] == pytest.approx(d["eta_amplitude"] * 50.0)
    assert d["first_unstable_bearing_number"] == pytest.approx(0.6)  # Lambda_c = 0.508 on 31x7
    with (tmp_path / "response.csv").open() as fh:
        rows = list(csv.DictReader(fh))
    assert len(rows) == 7 and [r["stable"] for r in rows] == ["1"] * 5 + ["0"] * 2
    assert (tmp_path / "response.png").stat().st_size > 20_000


def test_response_physical_unbalance_options(tmp_path, capsys):
    b = BearingParameters()
    code, out, err = run(
        capsys, "response", "--structure", "rigid", "--grid", "31x7", "--balance-grade", "2.5",
        "--speed-rpm", "20000", "--n-speeds", "2", "--out", tmp_path, "--json",
    )  # fmt: skip
    assert code == 0, err
    d = json.loads(out)
    assert d["unbalance"] == pytest.approx(Unbalance.from_iso1940(b, 2.5, 20000).magnitude, rel=1e-12)
    code, out, err = run(
        capsys, "response", "--structure", "rigid", "--grid", "31x7", "--unbalance-g-mm", "1.0",
        "--rotor-mass-kg", "2", "--speed-rpm", "20000", "--n-speeds", "2", "--out", tmp_path, "--json",
    )  # fmt: skip
    d2 = json.loads(out)
    assert d2["unbalance"] == pytest.approx(1e-6 / (2 * 50e-6))
    assert d2["unbalance_g_mm"] == pytest.approx(1.0)
    # linear in U
    assert d2["xi_amplitude"] / d["xi_amplitude"] == pytest.approx(d2["unbalance"] / d["unbalance"], rel=1e-6)


def test_simulate_with_unbalance(tmp_path, capsys):
    code, out, err = run(
        capsys, "simulate", "--structure", "rigid", "--grid", "31x7", "--bearing-number", "0.3",
        "--duration", "100", "--perturbation", "0", "0", "--unbalance", "0.02", "--out", tmp_path, "--json",
    )  # fmt: skip
    assert code == 0, err
    d = json.loads(out)
    assert d["unbalance"] == 0.02 and d["unbalance_g_mm"] == pytest.approx(0.02 * 0.37 * 50e-6 * 1e6)
    with (tmp_path / "trajectory.csv").open() as fh:
        xi = [float(r["xi"]) for r in csv.DictReader(fh)]
    assert max(xi) - min(xi) > 0.01  # the unbalance drives an orbit (without it the rotor stays put)


HOSTILE = [
    (["response", "--out", "{out}"], "--unbalance", "one of the arguments"),
    (["response", "--out", "{out}", "--unbalance", "1.5"], "--unbalance", "[0, 1)"),
    (["response", "--out", "{out}", "--unbalance", "0"], "--unbalance", "positive"),
    (
        ["response", "--out", "{out}", "--unbalance", "0.1", "--balance-grade", "2.5"],
        "--balance-grade",
        "not allowed",
    ),
    (["response", "--out", "{out}", "--unbalance-g-mm", "-3"], "--unbalance-g-mm", "positive"),
    (["response", "--out", "{out}", "--balance-grade", "nan"], "--balance-grade", "positive"),
    (["response", "--out", "{out}", "--unbalance-g-mm", "1e6"], "unbalance", "below 1"),
    (
        ["response", "--out", "{out}", "--unbalance", "0.1", "--rotor-mass-kg", "0"],
        "--rotor-mass-kg",
        "positive",
    ),
    (["response", "--out", "{out}", "--unbalance", "0.1", "--n-speeds", "1"], "--n-speeds", "[2, 1000]"),
    (
        ["response", "--out", "{out}", "--unbalance", "0.1", "--speed-range", "9", "3"],
        "--speed-range",
        "MIN < MAX",
    ),
    (["response", "--out", "{out}", "--unbalance", "0.1", "--grid", "313x25"], "--grid", "dense eigenvalue"),
    (["response", "--out", "{file}", "--unbalance", "0.1", "--grid", "313x25"], "--out", "not a folder"),
    (
        ["response", "--out", "{out}", "--unbalance", "0.1", "--bearing-number", "0.9", "--verify"],
        "--verify",
        "unstable",
    ),
    (
        ["simulate", "--out", "{out}", "--bearing-number", "0.3", "--duration", "1", "--unbalance", "-1"],
        "--unbalance",
        "[0, 1)",
    ),
    (
        [
            "simulate",
            "--out",
            "{out}",
            "--bearing-number",
            "0.3",
            "--duration",
            "1",
            "--unbalance-phase-deg",
            "inf",
        ],
        "--unbalance-phase-deg",
        "finite",
    ),
]


@pytest.mark.parametrize("argv,option,fragment", HOSTILE, ids=[" ".join(a[2:6]) for a, _, _ in HOSTILE])
def test_hostile_input_one_line_exit_2(tmp_path, capsys, argv, option, fragment):
    a_file = tmp_path / "file.txt"
    a_file.write_text("x")
    out = tmp_path / "out"
    argv = [a.replace("{out}", str(out)).replace("{file}", str(a_file)) for a in argv]
    if "--verify" not in argv:
        argv += ["--grid", "31x7"] if "--grid" not in argv else []
    assert_refused_at_once(main, argv, option, fragment, capsys, out)

import json
import subprocess
import sys

import pytest

from gfb_env.cli import main


def run(capsys, *argv):
    code = main(list(argv))
    out, err = capsys.readouterr()
    return code, out, err


def test_params_json(capsys):
    code, out, _ = run(capsys, "params", "--json")
    d = json.loads(out)
    assert code == 0
    for key in (
        "time_scale_s",
        "bearing_number",
        "mass_parameter",
        "gravity_parameter",
        "foil_stiffness",
        "kappa",
    ):
        assert key in d
    assert d["bearing_number"] == pytest.approx(0.5995, abs=1e-4)
    code, out, _ = run(capsys, "params", "--speed-rpm", "50000", "--json")
    assert json.loads(out)["bearing_number"] == pytest.approx(0.8326, abs=1e-4)


@pytest.mark.parametrize("structure", ["rigid", "elastic", "viscoelastic"])
def test_equilibrium_json_balances_load(capsys, structure):
    code, out, _ = run(
        capsys, "equilibrium", "--structure", structure, "--speed-rpm", "36000", "--grid", "41x7", "--json"
    )
    d = json.loads(out)
    assert code == 0
    assert d["bearing_force"] == pytest.approx(d["load"], rel=1e-8)
    assert d["load"] == pytest.approx(0.3, abs=1e-3)
    assert d["min_film_thickness"] == pytest.approx(1 - d["eccentricity"], abs=0.2)
    assert d["eccentricity_um"] == pytest.approx(50 * d["eccentricity"])
    assert d["bearing_force_N"] == pytest.approx(d["bearing_force"] * 73.54, rel=1e-3)
    for key in ("attitude_angle_deg", "max_pressure", "min_film_thickness_um"):
        assert key in d


def test_equilibrium_table(capsys):
    code, out, _ = run(
        capsys, "equilibrium", "--structure", "rigid", "--bearing-number", "0.6", "--grid", "21x5"
    )
    assert code == 0 and "eccentricity" in out and "attitude_angle_deg" in out


def test_simulate_writes_outputs(tmp_path, capsys):
    code, out, _ = run(
        capsys,
        "simulate",
        "--structure",
        "viscoelastic",
        "--bearing-number",
        "0.6",
        "--foil-stiffness",
        "1",
        "--foil-damping",
        "1",
        "--duration",
        "60",
        "--grid",
        "21x5",
        "--out",
        str(tmp_path),
        "--json",
    )
    assert code == 0
    d = json.loads(out)
    for key in (
        "max_eccentricity",
        "min_film_thickness",
        "whirl_frequency_ratio",
        "touchdown",
        "wall_time_s",
    ):
        assert key in d
    assert d["touchdown"] is False
    header = (tmp_path / "trajectory.csv").read_text().splitlines()[0]
    assert header == "tau,xi,eta,bearing_number,foil_damping,min_film_thickness,pressure_phi0_z0"
    assert (tmp_path / "simulation.png").stat().st_size > 10_000
    assert json.loads((tmp_path / "summary.json").read_text())["status"] == "done"


@pytest.mark.parametrize(
    "argv,fragment",
    [
        (["equilibrium", "--structure", "foam", "--bearing-number", "0.6"], "invalid choice"),
        (["equilibrium", "--bearing-number", "-0.6"], "--bearing-number must be finite and positive"),
        (["equilibrium", "--bearing-number", "0.6", "--speed-rpm", "3000"], "not allowed with"),
        (["equilibrium"], "required"),
        (["equilibrium", "--bearing-number", "0.6", "--grid", "79x8"], "n_z must be odd"),
        (["simulate", "--bearing-number", "0.6", "--duration", "0", "--out", "x"], "--duration"),
        (["params", "--speed-rpm", "fast"], "--speed-rpm must be a number"),
    ],
)
def test_bad_arguments_one_line_error_exit_2(capsys, argv, fragment):
    with pytest.raises(SystemExit) as exc:
        main(argv)
    _, err = capsys.readouterr()
    assert exc.value.code == 2
    assert fragment in err
    assert len(err.strip().splitlines()) == 1


def test_value_error_from_the_model_exits_2(capsys):
    code, _, err = run(
        capsys,
        "equilibrium",
        "--structure",
        "elastic",
        "--bearing-number",
        "0.6",
        "--foil-stiffness",
        "1e-12",
        "--grid",
        "13x5",
    )
    assert code in (1, 2)
    assert "error" in err and len(err.strip().splitlines()) == 1


def test_console_entry_point_help():
    out = subprocess.run(
        [sys.executable, "-m", "gfb_env", "simulate", "--help"], capture_output=True, text=True
    )
    assert out.returncode == 0
    assert "--foil-damping" in out.stdout and "--duration" in out.stdout

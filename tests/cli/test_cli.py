import json
import resource
import subprocess
import sys
import time
from pathlib import Path

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
    assert code == 0
    table = dict(line.split(None, 1) for line in out.strip().splitlines())
    # the table shows the same equilibrium as --json, and it carries the load (load balance)
    code, js, _ = run(
        capsys, "equilibrium", "--structure", "rigid", "--bearing-number", "0.6", "--grid", "21x5", "--json"
    )
    d = json.loads(js)
    assert float(table["eccentricity"]) == pytest.approx(d["eccentricity"], rel=1e-5)
    assert float(table["attitude_angle_deg"]) == pytest.approx(d["attitude_angle_deg"], rel=1e-5)
    assert float(table["bearing_force"]) == pytest.approx(float(table["load"]), rel=1e-6)
    assert 0.3 < d["eccentricity"] < 0.8 and 0 < d["attitude_angle_deg"] < 90  # ahead of the load


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


def test_no_equilibrium_exits_1_with_one_line(capsys):
    # a too-soft elastic foil is valid input with no equilibrium (paper Sect. 3.2): the solver reports
    # a failed computation, exit 1, not a usage error
    code, out, err = run(
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
    assert code == 1
    assert out == ""
    assert err.startswith("gfb equilibrium: error: no equilibrium found at Lambda=0.6")
    assert len(err.strip().splitlines()) == 1


def test_value_error_from_the_model_exits_2(capsys):
    # a ValueError raised in the handler (after parsing) by the model: the dense eigen-analysis limit
    code, out, err = run(capsys, "critical", "--grid", "157x25")
    assert code == 2 and out == ""
    assert err.startswith("gfb critical: error: --grid: grid 157x25 is too large for the dense eigenvalue")
    assert len(err.strip().splitlines()) == 1


# ---------------------------------------------------------------------------------- hostile input
def _main_exit(argv: list[str]) -> int:
    """Exit code of ``main``: argparse errors raise SystemExit, handler errors return the code."""
    try:
        return main(argv)
    except SystemExit as exc:
        return exc.code


@pytest.fixture
def a_file(tmp_path):
    p = tmp_path / "file.txt"
    p.write_text("not a folder")
    return p


# (argv with {file} / {out} placeholders, the option the message must name, a fragment of it)
HOSTILE = [
    (["equilibrium", "--grid", "2001x201", "--bearing-number", "0.6"], "--grid", "too large"),
    (["equilibrium", "--grid", "79x99999999999999999999", "--bearing-number", "0.6"], "--grid", "too large"),
    (
        ["simulate", "--bearing-number", "0.6", "--duration", "10", "--out", "{file}/out"],
        "--out",
        "is a file",
    ),
    (["simulate", "--bearing-number", "0.6", "--duration", "10", "--out", "{file}"], "--out", "not a folder"),
    (["map", "--foil-stiffness", "1", "--foil-damping", "1", "--out", "{file}/out"], "--out", "is a file"),
    (["map", "--out", "{file}"], "--out", "not a folder"),
    (
        [
            "simulate",
            "--bearing-number",
            "0.6",
            "--duration",
            "10",
            "--perturbation",
            "5",
            "0",
            "--out",
            "{out}",
        ],
        "--perturbation",
        "may move less than",
    ),
    (
        [
            "simulate",
            "--bearing-number",
            "0.6",
            "--duration",
            "1",
            "--perturbation",
            "nan",
            "0",
            "--out",
            "{out}",
        ],
        "--perturbation",
        "finite",
    ),
    (["simulate", "--bearing-number", "0.6", "--duration", "1e9", "--out", "{out}"], "--duration", "at most"),
    (["simulate", "--bearing-number", "0.6", "--duration", "inf", "--out", "{out}"], "--duration", "finite"),
    (["simulate", "--bearing-number", "0.6", "--duration", "-3", "--out", "{out}"], "--duration", "positive"),
    (
        [
            "simulate",
            "--bearing-number",
            "0.6",
            "--duration",
            "100",
            "--record-interval",
            "1e-9",
            "--out",
            "{out}",
        ],
        "--record-interval",
        "at most",
    ),
    (
        ["simulate", "--bearing-number", "0.6", "--duration", "10", "--touchdown", "-1", "--out", "{out}"],
        "--touchdown",
        "[0, 1)",
    ),
    (
        ["simulate", "--bearing-number", "0.6", "--duration", "10", "--touchdown", "nan", "--out", "{out}"],
        "--touchdown",
        "finite",
    ),
    (
        ["simulate", "--bearing-number", "nan", "--duration", "10", "--out", "{out}"],
        "--bearing-number",
        "finite",
    ),
    (["simulate", "--speed-rpm", "-5", "--duration", "10", "--out", "{out}"], "--speed-rpm", "positive"),
    (
        ["simulate", "--bearing-number", "0.6", "--foil-damping", "0", "--duration", "10", "--out", "{out}"],
        "--foil-damping",
        "positive",
    ),
    (["equilibrium", "--bearing-number", "0.6", "--foil-stiffness", "inf"], "--foil-stiffness", "finite"),
    (["critical", "--grid", "313x25"], "--grid", "dense eigenvalue"),
    (["critical", "--scan-step", "1e-9"], "--scan-step", "at most 1000"),
    (["critical", "--scan-step", "0"], "--scan-step", "positive"),
    (["critical", "--bearing-range", "3", "1"], "--bearing-range", "0 < MIN < MAX"),
    (["critical", "--bearing-range", "nan", "1"], "--bearing-range", "finite"),
    (["hysteresis", "--n-steps", "100000000"], "--n-steps", "[20, 2000]"),
    (["hysteresis", "--n-steps", "5"], "--n-steps", "[20, 2000]"),
    (["map", "--out", "{out}", "--n-jobs", "100000"], "--n-jobs", "cores"),
    (["map", "--out", "{out}", "--n-jobs", "0"], "--n-jobs", "cores"),
    (["map", "--out", "{out}", "--grid", "2001x201"], "--grid", "too large"),
    (["map", "--out", "{out}", "--grid", "313x25"], "--grid", "dense eigenvalue"),
    (["map", "--out", "{out}", "--foil-stiffness", "1,nan"], "--foil-stiffness", "positive"),
    (["map", "--out", "{out}", "--foil-damping", ",".join(["1"] * 1000)], "--foil-damping", "at most"),
]


@pytest.mark.parametrize("argv,option,fragment", HOSTILE, ids=[" ".join(a[:3])[:60] for a, _, _ in HOSTILE])
def test_hostile_input_one_line_exit_2_before_any_work(capsys, tmp_path, a_file, argv, option, fragment):
    out = tmp_path / "out"
    argv = [a.replace("{file}", str(a_file)).replace("{out}", str(out)) for a in argv]
    t0 = time.perf_counter()
    code = _main_exit(argv)
    wall = time.perf_counter() - t0
    stdout, err = capsys.readouterr()
    assert code == 2
    lines = err.strip().splitlines()
    assert len(lines) == 1, err
    assert lines[0].startswith(f"gfb {argv[0]}: error:")
    assert option in lines[0] and fragment in lines[0], lines[0]
    assert "Traceback" not in err and stdout == ""
    assert not out.exists()  # refused before anything was written
    assert wall < 20, f"{wall:.1f} s: heavy work before the refusal"  # the numba cache may load once


@pytest.mark.parametrize(
    "argv,option",
    [
        (["equilibrium", "--grid", "2001x201", "--bearing-number", "0.6"], "--grid"),
        (["equilibrium", "--grid", "79x99999999999999999999", "--bearing-number", "0.6"], "--grid"),
        (["simulate", "--bearing-number", "0.6", "--duration", "10", "--out", "{file}/out"], "--out"),
        (["map", "--out", "{file}/out"], "--out"),
    ],
)
def test_hostile_input_through_the_entry_point(tmp_path, a_file, argv, option):
    """The real process: exit status 2, one stderr line, no traceback, no heavy work.  The address
    space is capped at 3 GiB so that a regression fails instead of taking the machine's memory."""
    argv = [a.replace("{file}", str(a_file)) for a in argv]

    def cap_memory():
        resource.setrlimit(resource.RLIMIT_AS, (3 << 30, 3 << 30))

    t0 = time.perf_counter()
    proc = subprocess.run(
        [sys.executable, "-m", "gfb_env", *argv],
        capture_output=True,
        text=True,
        timeout=60,
        preexec_fn=cap_memory,
    )
    wall = time.perf_counter() - t0
    assert proc.returncode == 2, proc.stderr
    lines = [ln for ln in proc.stderr.splitlines() if ln.strip()]
    assert len(lines) == 1 and option in lines[0] and "Traceback" not in proc.stderr, proc.stderr
    assert proc.stdout == ""
    assert wall < 20


def test_check_output_dir_refuses_a_folder_without_write_permission(tmp_path, monkeypatch):
    from gfb_env import scripting

    # chmod does not stop root, so the permission answer itself is replaced
    monkeypatch.setattr(scripting.os, "access", lambda path, mode: Path(path) != tmp_path)
    with pytest.raises(ValueError, match=r"^--out .*: no permission to write in "):
        scripting.check_output_dir(str(tmp_path / "new" / "deeper"), "--out")
    with pytest.raises(ValueError, match="no permission"):
        scripting.check_output_dir(str(tmp_path), "--out")
    assert not (tmp_path / "new").exists()
    # a writable parent: accepted, and nothing is created
    monkeypatch.undo()
    assert scripting.check_output_dir(str(tmp_path / "new"), "--out") == tmp_path / "new"
    assert not (tmp_path / "new").exists()
    (tmp_path / "trajectory.csv").mkdir()
    with pytest.raises(ValueError, match="cannot write"):
        scripting.check_output_dir(str(tmp_path), "--out", ["trajectory.csv"])


def test_console_entry_point_help():
    out = subprocess.run(
        [sys.executable, "-m", "gfb_env", "simulate", "--help"], capture_output=True, text=True
    )
    assert out.returncode == 0
    assert "--foil-damping" in out.stdout and "--duration" in out.stdout

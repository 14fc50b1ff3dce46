"""The ``gfb`` command as a package (issue 18, section 4) and the defects a new user hit (issue 18, section 6:
1, 2, 4, 5, 15): each test here fails on the code before the fix."""

from __future__ import annotations

import ast
import json
import os
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

import gfb_env
from gfb_env.cli import COMMAND_MODULES, build_parser, main
from gfb_env.params import MAX_BEARING_FILE_BYTES, BearingParameters, shipped_bearing_names

REPO = Path(__file__).resolve().parents[2]
CLI = REPO / "gfb_env" / "cli"


def run(capsys, *argv):
    code = main([str(a) for a in argv])
    out, err = capsys.readouterr()
    return code, out, err


def one_line_exit_2(capsys, *argv) -> str:
    """The error line of a usage error (argparse exits, a handler returns 2)."""
    try:
        code = main([str(a) for a in argv])
    except SystemExit as exc:
        code = exc.code
    _, err = capsys.readouterr()
    lines = err.strip().splitlines()
    assert code == 2 and len(lines) == 1, (code, err)
    return lines[0]


# ---------------------------------------------------------------------------------------- layout
def test_every_command_module_registers_and_none_imports_the_package_init():
    """One module per group, each with register(); no module of the package imports gfb_env.cli itself
    (the old circle cli <-> cli_engineering)."""
    sub = build_parser()._subparsers._group_actions[0]
    assert list(sub.choices) == [
        "params", "bearing", "equilibrium", "simulate", "critical", "hysteresis", "map", "campbell",
        "runup", "schedule", "response",
    ]  # fmt: skip
    for name in COMMAND_MODULES:
        tree = ast.parse((CLI / f"{name}.py").read_text())
        for node in ast.walk(tree):
            if isinstance(node, ast.ImportFrom):
                assert node.module != "gfb_env.cli", f"gfb_env/cli/{name}.py imports gfb_env.cli"
        assert any(isinstance(n, ast.FunctionDef) and n.name == "register" for n in tree.body), name
    # each imports on its own in a fresh interpreter (no import order dependence)
    code = "; ".join(f"import gfb_env.cli.{name}" for name in COMMAND_MODULES)
    subprocess.run([sys.executable, "-c", code], check=True, timeout=300)


def test_no_module_imports_the_retired_private_helpers():
    for folder in ("gfb_env", "agents", "experiments", "tests"):
        for f in (REPO / folder).rglob("*.py"):
            text = f.read_text()
            for old in ("_cli_common", "gfb_env._plotting", "gfb_env.cli_"):
                assert old not in text or f.name == Path(__file__).name, f"{f} uses {old}"


def test_version(capsys):
    with pytest.raises(SystemExit) as exc:
        main(["--version"])
    out, _ = capsys.readouterr()
    assert exc.value.code == 0 and out.strip() == f"gfb {gfb_env.cli.version()}"
    assert gfb_env.cli.version() == gfb_env.__version__  # the checkout and its metadata agree


def test_python_dash_m_is_the_gfb_command():
    res = subprocess.run(
        [sys.executable, "-m", "gfb_env", "params", "--json"], capture_output=True, text=True, timeout=300
    )
    assert res.returncode == 0 and json.loads(res.stdout)["kappa"] == 0.5, res.stderr


# ------------------------------------------------------------------- defect 1: shipped bearings
def test_shipped_bearing_by_name(capsys):
    assert set(shipped_bearing_names()) == {"table1", "table1_frictional", "small_turbocompressor"}
    code, out, _ = run(capsys, "bearing", "--bearing", "small_turbocompressor", "--json")
    path = REPO / "gfb_env" / "data" / "bearings" / "small_turbocompressor.toml"
    assert code == 0 and json.loads(out)["parameters"] == BearingParameters.from_toml(path).as_dict()
    code, out2, _ = run(capsys, "bearing", "--bearing", "small_turbocompressor.toml", "--json")
    assert out2 == out
    assert BearingParameters.from_toml(path.with_name("table1.toml")) == BearingParameters()
    # the examples/ path of the README still works in a checkout
    code, out3, _ = run(
        capsys, "bearing", "--bearing", "examples/bearings/small_turbocompressor.toml", "--json"
    )
    assert code == 0 and json.loads(out3)["parameters"] == json.loads(out)["parameters"]
    line = one_line_exit_2(capsys, "bearing", "--bearing", "no_such_bearing")
    shipped = "small_turbocompressor, table1, table1_frictional"
    assert f"no such file, nor the name of a shipped bearing ({shipped})" in line


def test_help_names_the_shipped_bearings(capsys):
    with pytest.raises(SystemExit):
        main(["bearing", "--help"])
    out, _ = capsys.readouterr()
    assert "small_turbocompressor" in out and "table1" in out


# ------------------------------------------------------------ defect 2: --json needs no --out
def test_response_json_needs_no_output_folder(capsys, tmp_path, monkeypatch):
    """The docs/engineering.md command (on a coarse grid to keep the test fast)."""
    monkeypatch.chdir(tmp_path)
    code, out, err = run(
        capsys, "response", "--foil-damping", "4", "--unbalance", "0.0159155", "--speed-rpm", "29922.853",
        "--grid", "21x5", "--n-speeds", "3", "--json",
    )  # fmt: skip
    assert code == 0, err
    d = json.loads(out)
    assert d["files"] == {} and d["speed_rpm"] == pytest.approx(29922.853)
    assert list(tmp_path.iterdir()) == []  # nothing written


def test_simulate_without_out_writes_nothing(capsys, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    code, out, err = run(
        capsys, "simulate", "--bearing-number", "0.6", "--grid", "21x5", "--duration", "5", "--json"
    )
    assert code == 0 and json.loads(out)["status"] == "done", err
    assert list(tmp_path.iterdir()) == []


@pytest.mark.parametrize("command", ["simulate", "campbell", "runup", "schedule", "map", "response"])
def test_out_is_optional_everywhere(command):
    required = {
        "simulate": ["--bearing-number", "0.6", "--duration", "5"],
        "schedule": ["--target-rpm", "30000"],
        "response": ["--unbalance", "0.01"],
    }
    args = build_parser().parse_args([command, *required.get(command, []), "--json"])
    assert args.out is None


# ---------------------------------------------------------- defect 4: hostile bearing files
def _hostile_files(tmp_path: Path) -> dict[str, tuple[Path, str]]:
    fifo = tmp_path / "pipe.toml"
    os.mkfifo(fifo)
    big = tmp_path / "big.toml"
    big.write_text("# " + "x" * MAX_BEARING_FILE_BYTES + "\n")
    deep = tmp_path / "deep.toml"
    deep.write_text("length_m = " + "[" * 5000 + "]" * 5000 + "\n")
    return {
        "device": (Path("/dev/zero"), "not a regular file"),
        "fifo": (fifo, "not a regular file"),
        "big": (big, f"a bearing file has at most {MAX_BEARING_FILE_BYTES} bytes"),
        "deep": (deep, "nested too deeply"),
    }


@pytest.mark.skipif(not Path("/dev/zero").exists() or not hasattr(os, "mkfifo"), reason="POSIX only")
def test_hostile_bearing_files_refused_before_reading(tmp_path):
    for kind, (path, fragment) in _hostile_files(tmp_path).items():
        t0 = time.perf_counter()
        with pytest.raises(ValueError) as exc:
            BearingParameters.from_toml(path)
        assert fragment in str(exc.value) and "\n" not in str(exc.value), (kind, exc.value)
        assert time.perf_counter() - t0 < 5.0, kind


@pytest.mark.skipif(not Path("/dev/zero").exists() or not hasattr(os, "mkfifo"), reason="POSIX only")
def test_hostile_bearing_files_through_the_command(tmp_path):
    """A subprocess with a timeout: the named pipe hung forever and /dev/zero read until MemoryError."""
    for kind, (path, fragment) in _hostile_files(tmp_path).items():
        res = subprocess.run(
            [sys.executable, "-m", "gfb_env", "bearing", "--bearing", str(path)],
            capture_output=True, text=True, timeout=120,
        )  # fmt: skip
        lines = res.stderr.strip().splitlines()
        assert res.returncode == 2 and len(lines) == 1 and fragment in lines[0], (kind, res.stderr[-2000:])


# ------------------------------------------------------------------ defect 5: unwritable --out
@pytest.mark.skipif(not Path("/proc").is_dir(), reason="needs /proc (Linux)")
@pytest.mark.parametrize(
    "argv",
    [
        ["simulate", "--bearing-number", "0.6", "--duration", "5"],
        ["campbell"],
        ["map"],
        ["runup"],
        ["schedule", "--target-rpm", "30000"],
        ["response", "--unbalance", "0.01"],
    ],
)
def test_unwritable_out_refused_before_any_work(capsys, monkeypatch, argv):
    """/proc accepts os.access(W_OK) for root, so only a real write tells; the computation (schedule:
    over a minute) must not run: the analysis entry points raise if they are reached."""

    def must_not_run(*a, **k):
        raise AssertionError("the computation ran before --out was checked")

    import gfb_env.analysis.campbell as campbell
    import gfb_env.analysis.maps as maps
    import gfb_env.analysis.response as response
    import gfb_env.analysis.runup as runup
    import gfb_env.analysis.schedule as schedule
    import gfb_env.cli.simulate as simulate

    for mod, name in ((campbell, "campbell_diagram"), (maps, "compute_stability_map"), (runup, "run_up"),
                      (schedule, "design_run_up_schedule"), (response, "response_curve"),
                      (response, "unbalance_response"), (simulate, "find_equilibrium")):  # fmt: skip
        monkeypatch.setattr(mod, name, must_not_run)
    line = one_line_exit_2(capsys, *argv, "--grid", "21x5", "--out", "/proc/nonexistent/out")
    assert "--out /proc/nonexistent/out: cannot write in /proc" in line, line


def test_output_probe_leaves_nothing_behind(tmp_path):
    from gfb_env.scripting import check_output_dir

    assert check_output_dir(str(tmp_path / "a" / "b")) == tmp_path / "a" / "b"
    assert list(tmp_path.iterdir()) == []


# -------------------------------------------------------- defect 15: empty list items, ranges
@pytest.mark.parametrize("value", ["1,,2", "1,2,", ",1", "1, ,2"])
def test_map_refuses_empty_list_items(capsys, tmp_path, value):
    line = one_line_exit_2(capsys, "map", "--foil-damping", value, "--out", tmp_path / "out")
    assert line.startswith("gfb map: error: --foil-damping has an empty item"), line
    assert not (tmp_path / "out").exists()


def test_float_list_keeps_the_accepted_forms():
    from gfb_env.scripting import float_list

    assert float_list("0.3,1,3", "--x") == [0.3, 1.0, 3.0]
    assert float_list("0.3 1 3", "--x") == [0.3, 1.0, 3.0]
    assert float_list(" 0.3, 1 ,3 ", "--x") == [0.3, 1.0, 3.0]
    for bad in ("", " ", "a", "1,-2", "nan", "inf"):
        with pytest.raises(ValueError, match="--x"):
            float_list(bad, "--x")


def test_command_range_outside_the_motor_is_refused():
    import gymnasium as gym

    for bad in [(0.0, 1e12), (45_000.0, 1e12)]:
        with pytest.raises(ValueError, match=r"^command_range_rpm must lie above the start speed"):
            gym.make("gfb_env/RunUpRandomized-v2", command_range_rpm=bad)
    env = gym.make("gfb_env/RunUpRandomized-v2", command_range_rpm=(45_000.0, 50_000.0))
    assert env.unwrapped.command_range_rpm == (45_000.0, 50_000.0)


# ------------------------------------------------------ a computation failure is exit 1
def test_a_solver_failure_is_exit_1_with_one_line(capsys, monkeypatch):
    """A singular Jacobian (numpy's LinAlgError is a ValueError, which meant exit 2: bad input)."""
    import gfb_env.cli.static as static

    def singular(*a, **k):
        raise np.linalg.LinAlgError("Singular matrix")

    monkeypatch.setattr(static, "find_equilibrium", singular)
    code, _, err = run(capsys, "equilibrium", "--bearing-number", "0.6", "--grid", "21x5")
    assert code == 1 and err.strip() == "gfb equilibrium: error: Singular matrix", err


def test_a_several_line_failure_is_still_one_line(capsys, monkeypatch):
    import gfb_env.cli.static as static
    from gfb_env.equilibrium import EquilibriumError

    def fails(*a, **k):
        raise EquilibriumError("Newton did not converge\n  residual 1e-3\n")

    monkeypatch.setattr(static, "find_equilibrium", fails)
    code, _, err = run(capsys, "equilibrium", "--bearing-number", "0.6", "--grid", "21x5")
    assert code == 1 and err == "gfb equilibrium: error: Newton did not converge; residual 1e-3\n", err

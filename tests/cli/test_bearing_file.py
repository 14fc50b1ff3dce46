"""Bearing files (``--bearing``), ``gfb bearing`` and the validation of the dimensional path (issue 12)."""

import json
from dataclasses import fields
from pathlib import Path

import pytest

from gfb_env.bearing_report import LBF_IN3_KRPM_TO_SI, bearing_report, dellacorte_load_capacity_n
from gfb_env.cli import main
from gfb_env.model import GFBModel
from gfb_env.params import BearingParameters

EXAMPLES = Path(__file__).resolve().parents[2] / "examples" / "bearings"
TABLE1 = EXAMPLES / "table1.toml"
SMALL = EXAMPLES / "small_turbocompressor.toml"


def run(capsys, *argv):
    code = main([str(a) for a in argv])
    out, err = capsys.readouterr()
    return code, out, err


def write(tmp_path, text: str) -> Path:
    p = tmp_path / "bearing.toml"
    p.write_text(text)
    return p


# ------------------------------------------------------------------------------------ reading
def test_table1_file_is_table1_and_every_key_is_a_field():
    assert BearingParameters.from_toml(TABLE1) == BearingParameters()
    import tomllib

    names = {f.name for f in fields(BearingParameters)}
    for path in (TABLE1, SMALL):
        keys = set(tomllib.loads(path.read_text()))
        assert keys <= names
    assert set(tomllib.loads(TABLE1.read_text())) == names  # the Table-1 file documents every key


def test_missing_keys_take_table1(tmp_path):
    b = BearingParameters.from_toml(write(tmp_path, "clearance_m = 40e-6\nbump_count = 26.0\n"))
    assert b == BearingParameters(clearance_m=40e-6)
    assert isinstance(b.bump_count, int)


@pytest.mark.parametrize(
    "text,fragment",
    [
        ("lenght_m = 0.03\n", "unknown key 'lenght_m' (did you mean 'length_m'?)"),
        ("colour = 3\n", "unknown key 'colour' (known keys: length_m"),
        ("clearance_m = -5e-6\n", "clearance_m must be positive"),
        ("clearance_m = '50 um'\n", "clearance_m must be a number, got '50 um'"),
        ("clearance_m = true\n", "clearance_m must be a number"),
        ("clearance_m = nan\n", "clearance_m must be finite"),
        ("radius_m = inf\n", "radius_m must be finite"),
        ("youngs_modulus_pa = 1" + "0" * 400 + "\n", "youngs_modulus_pa is too large"),
        ("bump_count = 26.5\n", "bump_count must be a positive integer"),
        ("clearance_m = 1e-3\n", "clearance_m must be much smaller than radius_m"),
        ("[rotor]\nmass = 1\n", "[rotor] is a table; the keys must be flat"),
        ("length_m = [1, 2]\n", "length_m must be a number"),
        ("length_m = \n", "TOML syntax error"),
    ],
)
def test_bad_files_one_line_naming_the_key(tmp_path, text, fragment):
    p = write(tmp_path, text)
    with pytest.raises(ValueError) as exc:
        BearingParameters.from_toml(p)
    msg = str(exc.value)
    assert msg.startswith(str(p)) and fragment in msg and "\n" not in msg, msg


def test_unreadable_files(tmp_path):
    with pytest.raises(ValueError, match="no such file"):
        BearingParameters.from_toml(tmp_path / "nope.toml")
    with pytest.raises(ValueError, match="is a folder"):
        BearingParameters.from_toml(tmp_path)
    (tmp_path / "bin.toml").write_bytes(b"\xff\xfe\x00")
    with pytest.raises(ValueError, match="not a UTF-8"):
        BearingParameters.from_toml(tmp_path / "bin.toml")


@pytest.mark.parametrize(
    "command",
    [
        ["params"],
        ["bearing"],
        ["equilibrium", "--bearing-number", "0.6"],
        ["simulate", "--bearing-number", "0.6", "--duration", "10", "--out", "{out}"],
        ["critical"],
        ["hysteresis"],
        ["map", "--out", "{out}"],
        ["campbell", "--out", "{out}"],
        ["runup", "--out", "{out}"],
    ],
)
def test_every_subcommand_refuses_a_bad_bearing_file_exit_2(tmp_path, capsys, command):
    p = write(tmp_path, "viscosity_pa_s = 0\n")
    argv = [a.replace("{out}", str(tmp_path / "out")) for a in command] + ["--bearing", str(p)]
    with pytest.raises(SystemExit) as exc:
        main(argv)
    _, err = capsys.readouterr()
    lines = err.strip().splitlines()
    assert exc.value.code == 2 and len(lines) == 1, err
    assert lines[0].startswith(f"gfb {command[0]}: error: argument --bearing: {p}: viscosity_pa_s")
    assert not (tmp_path / "out").exists()


# ------------------------------------------------------------------------------ gfb bearing
def test_gfb_bearing_json_groups_match_the_parameters(capsys):
    code, out, _ = run(capsys, "bearing", "--bearing", SMALL, "--json")
    d = json.loads(out)
    b = BearingParameters.from_toml(SMALL)
    assert code == 0
    assert d["parameters"] == b.as_dict()
    assert d["bearing_number"] == pytest.approx(b.bearing_number_at(b.speed_rpm))
    assert d["bearing_number_per_1000_rpm"] * b.speed_rpm / 1000 == pytest.approx(d["bearing_number"])
    for key in ("mass_parameter", "gravity_parameter", "foil_stiffness", "kappa", "time_scale_s"):
        assert d[key] == pytest.approx(getattr(b, key))
    assert d["load"] == pytest.approx(b.mass_parameter * b.gravity_parameter)
    # W / (p0 L D) is half the model's nondimensional load M G = W / (p0 R L)
    assert d["static_load_ratio"] == pytest.approx(d["load"] / 2)
    assert d["static_load_n"] == pytest.approx(0.5 * 9.81)
    assert d["specific_load_kpa"] == pytest.approx(4.905 / (0.025 * 0.025) / 1e3)
    assert d["warnings"] == []


def test_dellacorte_rule_in_si_matches_the_rule_in_inches():
    # Table 1: L = D = 1.5 in, 36 krpm, D_c = 0.1: W_max = 0.1 * 2.25 * 1.5 * 36 = 12.15 lbf
    b = BearingParameters()
    assert dellacorte_load_capacity_n(b, 36_000) == pytest.approx(12.15 * 4.4482216152605, rel=1e-9)
    assert LBF_IN3_KRPM_TO_SI == pytest.approx(271_447, rel=1e-5)


def test_warnings_fire_for_an_overloaded_loose_bearing():
    heavy = BearingParameters(external_load_per_bearing_n=600.0, clearance_m=150e-6)
    r = bearing_report(heavy)
    text = " | ".join(r["warnings"])
    assert "above 340 kPa" in text and "34 kPa (5 psi) start-up" in text
    assert "exceeds DellaCorte" in text and "C/R = 0.00787" in text
    assert r["dellacorte_load_ratio"] > 1
    fast = bearing_report(BearingParameters(), speed_rpm=200_000)
    assert any("surface speed" in w for w in fast["warnings"])
    assert bearing_report(BearingParameters())["warnings"] == []


def test_gfb_bearing_text_prints_warnings(capsys, tmp_path):
    p = write(tmp_path, "external_load_per_bearing_n = 100.0\n")
    code, out, _ = run(capsys, "bearing", "--bearing", p)
    assert code == 0 and "warning: specific load W/(L D) = 7" in out


# ------------------------------------------------------------------ --bearing through the model
def test_critical_json_keeps_its_keys_and_takes_k_w_from_the_file(capsys):
    base = ["critical", "--bearing", SMALL, "--grid", "41x7", "--bearing-range", "0.1", "0.5", "--json"]
    code, out, _ = run(capsys, *base)
    d = json.loads(out)
    b = BearingParameters.from_toml(SMALL)
    assert code == 0
    for key in ("critical_bearing_number", "critical_speed_rpm", "whirl_frequency_ratio", "foil_stiffness"):
        assert key in d
    assert d["foil_stiffness"] == pytest.approx(b.foil_stiffness)
    assert d["critical_speed_rpm"] == pytest.approx(b.speed_rpm_at(d["critical_bearing_number"]))
    code, out, _ = run(capsys, *base, "--foil-stiffness", "1.0")
    d1 = json.loads(out)
    assert d1["foil_stiffness"] == 1.0
    assert d1["critical_bearing_number"] != pytest.approx(d["critical_bearing_number"], abs=1e-4)


def test_params_and_equilibrium_use_the_file(capsys):
    b = BearingParameters.from_toml(SMALL)
    code, out, _ = run(capsys, "params", "--bearing", SMALL, "--json")
    assert json.loads(out)["bearing_number"] == pytest.approx(b.bearing_number)
    code, out, _ = run(
        capsys, "equilibrium", "--bearing", SMALL, "--speed-rpm", "8000", "--grid", "41x7", "--json"
    )
    d = json.loads(out)
    assert code == 0 and d["load"] == pytest.approx(b.mass_parameter * b.gravity_parameter)
    assert d["eccentricity_um"] == pytest.approx(30 * d["eccentricity"])


# ------------------------------------------------------------------------------ validation
def test_table1_file_reproduces_the_paper_grid_rigid_onset(capsys):
    """Issue 12, Sect. 4: rigid Lambda_c 0.5099 and 30 621 rpm on the paper grid 79x7 (~3 s)."""
    code, out, _ = run(
        capsys, "critical", "--structure", "rigid", "--bearing", TABLE1, "--bearing-range", "0.3", "0.7",
        "--json",
    )  # fmt: skip
    d = json.loads(out)
    assert code == 0 and d["grid"] == "79x7"
    assert d["critical_bearing_number"] == pytest.approx(0.5099, abs=5e-5)
    assert d["critical_speed_rpm"] == pytest.approx(30_621, abs=3)


def scaled(b: BearingParameters, s: float, k: float, p: float) -> BearingParameters:
    """Lengths x s, viscosity x k, pressure (and E_B) x p, with the mass and loads that keep
    M, G, K_W and kappa: m x k^2 s / p, g and F_L/m x p^2 s / k^2 (so F_L x p s^2)."""
    lengths = ("length_m", "radius_m", "clearance_m", "bump_half_width_m", "bump_foil_thickness_m")
    ch = {n: getattr(b, n) * s for n in lengths}
    ch["top_foil_thickness_m"] = b.top_foil_thickness_m * s
    ch["viscosity_pa_s"] = b.viscosity_pa_s * k
    ch["ambient_pressure_pa"] = b.ambient_pressure_pa * p
    ch["youngs_modulus_pa"] = b.youngs_modulus_pa * p
    ch["rotor_mass_per_bearing_kg"] = b.rotor_mass_per_bearing_kg * k**2 * s / p
    ch["gravity_m_s2"] = b.gravity_m_s2 * p**2 * s / k**2
    ch["external_load_per_bearing_n"] = b.external_load_per_bearing_n * p * s**2
    return b.replace(**ch)


@pytest.mark.parametrize("structure", ["rigid", "viscoelastic"])
def test_similar_bearing_same_onset_rpm_scaled_by_p_over_k(structure):
    """A bearing scaled (lengths x 3, viscosity x 1.5, pressure x 2) with identical groups has the
    same Lambda_c to solver precision, and its critical speed scales as T^-1, i.e. by p / k."""
    from gfb_env.analysis import critical_bearing_number

    s, k, p = 3.0, 1.5, 2.0
    a = BearingParameters()
    b = scaled(a, s, k, p)
    na, nb = a.nondimensional(), b.nondimensional()
    for f in ("mass_parameter", "gravity_parameter", "foil_stiffness", "kappa"):
        assert getattr(nb, f) == pytest.approx(getattr(na, f), rel=1e-12)
    assert b.time_scale_s == pytest.approx(a.time_scale_s * k / p, rel=1e-12)
    ca = critical_bearing_number(GFBModel(structure, "41x7", bearing=a), 1.0, (0.3, 0.9))
    cb = critical_bearing_number(GFBModel(structure, "41x7", bearing=b), 1.0, (0.3, 0.9))
    assert cb.critical_bearing_number == pytest.approx(ca.critical_bearing_number, abs=1e-9)
    assert cb.critical_speed_rpm == pytest.approx(ca.critical_speed_rpm * p / k, rel=1e-9)


def test_map_with_a_bearing_file_uses_its_groups(tmp_path, capsys):
    """The bearing travels through the sweep (as a dict in each point) into every map model."""
    from gfb_env.analysis import critical_bearing_number

    code, out, _ = run(
        capsys, "map", "--bearing", SMALL, "--foil-stiffness", "1", "--foil-damping", "1", "--grid", "21x5",
        "--out", tmp_path, "--json",
    )  # fmt: skip
    d = json.loads(out)
    assert code == 0
    b = BearingParameters.from_toml(SMALL)
    ref = critical_bearing_number(GFBModel("rigid", "21x5", bearing=b), 1.0)
    assert d["rigid_critical_bearing_number"] == pytest.approx(ref.critical_bearing_number, abs=1e-9)
    rows = (tmp_path / "stability_map.csv").read_text().splitlines()
    rigid = [r for r in rows if r.startswith("rigid")][0].split(",")
    assert float(rigid[4]) == pytest.approx(b.speed_rpm_at(ref.critical_bearing_number), rel=1e-6)

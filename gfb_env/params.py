"""Dimensional parameters of a gas foil bearing (GFB) rotor system and their nondimensional form.

The defaults are Table 1 of Leister, Baum & Seemann, *On the importance of frictional energy
dissipation in the prevention of undesirable self-excited vibrations in gas foil bearing rotor
systems* (Technische Mechanik, 2017), a first-generation bump-type GFB.

Nondimensionalisation (paper, Sect. 2.2-2.4):

* time scale            ``T      = 6 mu0 / p0 (R/C)^2``               (``tau = t / T``)
* bearing number        ``Lambda = 6 mu0 omega0 / p0 (R/C)^2 = omega0 T``
* rotor mass            ``M      = p0 / (36 mu0^2 L) (C/R)^5 m``
* modified gravity      ``G      = 36 mu0^2 / (p0^2 R) (R/C)^5 (g + F_L/m)``
* foil stiffness        ``K_W    = E_B C / [2 (1 - nu_B^2) p0 l_S] (t_B/l_B)^3`` (Walowit & Anno)
* geometry              ``kappa  = R / L``

Lengths are scaled by the clearance C, pressures by p0 and bearing forces by ``p0 R L``.

Note on the time scale: the paper states that ``tau_max = 50 000`` corresponds to ``t_max = 50 s``;
with its own ``T = 1.590e-4 s`` that is 7.95 s.  We use the formulas, never the quoted seconds.
"""

from __future__ import annotations

import functools
import math
import os
import stat
import tomllib
from collections.abc import Mapping
from dataclasses import asdict, dataclass, fields, replace
from pathlib import Path
from typing import Any

__all__ = [
    "BearingParameters",
    "FrictionParameters",
    "MAX_BEARING_FILE_BYTES",
    "NondimensionalParameters",
    "check_positive",
    "read_bearing_file",
    "shipped_bearing_names",
    "shipped_bearing_path",
]

_RPM_TO_RAD_S = 2.0 * math.pi / 60.0
#: Largest bearing file read (1 MiB): a bearing file is a few dozen lines; anything larger (a device,
#: a log file given by mistake) is refused before it is read.
MAX_BEARING_FILE_BYTES = 1 << 20
#: The bearing files shipped with the package (``gfb_env/data/bearings/NAME.toml``).
_SHIPPED_BEARINGS = Path(__file__).resolve().parent / "data" / "bearings"


def shipped_bearing_names() -> tuple[str, ...]:
    """Names of the bearing files shipped with the package (``table1``, ``small_turbocompressor``)."""
    return tuple(sorted(f.stem for f in _SHIPPED_BEARINGS.glob("*.toml")))


def shipped_bearing_path(name: str) -> Path:
    """The path of the shipped bearing file ``name`` (with or without ``.toml``).

    Raises:
        ValueError: naming the shipped bearings when there is none of that name.
    """
    stem = name[: -len(".toml")] if name.endswith(".toml") else name
    if stem not in shipped_bearing_names():
        raise ValueError(f"no shipped bearing {name!r} (shipped: {', '.join(shipped_bearing_names())})")
    return _SHIPPED_BEARINGS / f"{stem}.toml"


def check_positive(name: str, value: float) -> float:
    """``float(value)`` if finite and positive, else ``ValueError`` naming ``name``."""
    value = float(value)
    if not (math.isfinite(value) and value > 0):
        raise ValueError(f"{name} must be finite and positive, got {value!r}")
    return value


@dataclass(frozen=True)
class NondimensionalParameters:
    """The nondimensional groups the model needs (symbols of the paper in brackets).

    Attributes:
        mass_parameter: rotor mass per bearing ``M``.
        gravity_parameter: modified gravity ``G`` (gravity plus static load per unit mass).
        foil_stiffness: foundation stiffness ``K_W``.
        kappa: geometry ratio ``R / L``.
    """

    mass_parameter: float
    gravity_parameter: float
    foil_stiffness: float
    kappa: float

    def __post_init__(self) -> None:
        for f in fields(self):
            value = getattr(self, f.name)
            if not (isinstance(value, (int, float)) and math.isfinite(value) and value > 0):
                raise ValueError(f"{f.name} must be a finite positive number, got {value!r}")

    @property
    def load(self) -> float:
        """Nondimensional static load per bearing ``M G`` (equals the bearing force at equilibrium)."""
        return self.mass_parameter * self.gravity_parameter


@dataclass(frozen=True)
class BearingParameters:
    """Dimensional bearing, foil and rotor parameters (SI units), Table 1 of the paper by default.

    Every field is validated on construction; an invalid value raises ``ValueError`` naming the field.

    Attributes:
        length_m: axial bearing width ``L``.
        radius_m: bearing (undeformed foil) radius ``R``.
        clearance_m: nominal radial clearance ``C = R - r``; must satisfy ``0 < C/R << 1``.
        ambient_pressure_pa: ambient pressure ``p0``.
        viscosity_pa_s: dynamic gas viscosity ``mu0``.
        speed_rpm: nominal rotor speed ``n0`` (only used as a default operating point).
        rotor_mass_per_bearing_kg: half the rotor mass, ``m``.
        gravity_m_s2: gravitational acceleration ``g``.
        external_load_per_bearing_n: static load per bearing ``F_L``.
        bump_count: number of bumps ``N_B``.
        bump_half_width_m: half the bump width, ``l_B``.
        bump_foil_thickness_m: bump foil thickness ``t_B``.
        top_foil_thickness_m: top foil thickness ``t_T`` (not used by the foundation model).
        youngs_modulus_pa: bump foil Young's modulus ``E_B``.
        poisson_ratio: bump foil Poisson's ratio ``nu_B``, in (-1, 0.5).
    """

    length_m: float = 38.10e-3
    radius_m: float = 19.05e-3
    clearance_m: float = 50e-6
    ambient_pressure_pa: float = 101_325.0
    viscosity_pa_s: float = 1.85e-5
    speed_rpm: float = 36_000.0
    rotor_mass_per_bearing_kg: float = 0.185
    gravity_m_s2: float = 9.81
    external_load_per_bearing_n: float = 20.25
    bump_count: int = 26
    bump_half_width_m: float = 1.778e-3
    bump_foil_thickness_m: float = 101.6e-6
    top_foil_thickness_m: float = 101.6e-6
    youngs_modulus_pa: float = 214e9
    poisson_ratio: float = 0.29

    def __post_init__(self) -> None:
        positive = {
            "length_m",
            "radius_m",
            "clearance_m",
            "ambient_pressure_pa",
            "viscosity_pa_s",
            "rotor_mass_per_bearing_kg",
            "bump_half_width_m",
            "bump_foil_thickness_m",
            "top_foil_thickness_m",
            "youngs_modulus_pa",
        }
        for f in fields(self):
            value = getattr(self, f.name)
            if isinstance(value, bool) or not isinstance(value, (int, float)):
                raise ValueError(f"{f.name} must be a number, got {value!r}")
            if not math.isfinite(value):
                raise ValueError(f"{f.name} must be finite, got {value!r}")
            if f.name in positive and value <= 0:
                raise ValueError(f"{f.name} must be positive, got {value!r}")
        if self.speed_rpm < 0:
            raise ValueError(f"speed_rpm must be non-negative, got {self.speed_rpm!r}")
        if self.gravity_m_s2 < 0:
            raise ValueError(f"gravity_m_s2 must be non-negative, got {self.gravity_m_s2!r}")
        if self.external_load_per_bearing_n < 0:
            raise ValueError(
                f"external_load_per_bearing_n must be non-negative, got {self.external_load_per_bearing_n!r}"
            )
        if self.gravity_m_s2 + self.external_load_per_bearing_n / self.rotor_mass_per_bearing_kg <= 0:
            raise ValueError("gravity_m_s2 and external_load_per_bearing_n: the static load must be positive")
        if int(self.bump_count) != self.bump_count or self.bump_count < 1:
            raise ValueError(f"bump_count must be a positive integer, got {self.bump_count!r}")
        if not (-1.0 < self.poisson_ratio < 0.5):
            raise ValueError(f"poisson_ratio must lie in (-1, 0.5), got {self.poisson_ratio!r}")
        # Eq. (1): the film model linearises in C/R; 2 % is already a very loose bearing.
        if self.clearance_m >= 0.02 * self.radius_m:
            raise ValueError(
                f"clearance_m must be much smaller than radius_m (C/R < 0.02), got C/R = "
                f"{self.clearance_m / self.radius_m:.3g}"
            )
        if self.bump_half_width_m >= self.bump_pitch_m:
            raise ValueError(
                "bump_half_width_m must be smaller than the bump pitch 2 pi R / N_B = "
                f"{self.bump_pitch_m:.4g} m"
            )

    # ----------------------------------------------------------------------------------------
    # derived nondimensional values
    @property
    def bump_pitch_m(self) -> float:
        """Bump distance ``l_S = 2 pi R / N_B``."""
        return 2.0 * math.pi * self.radius_m / self.bump_count

    @functools.cached_property
    def time_scale_s(self) -> float:
        """Characteristic time ``T = 6 mu0 / p0 (R/C)^2`` in seconds (computed once per bearing: the
        envs convert with it ~20 times per control step; the fields are frozen)."""
        return 6.0 * self.viscosity_pa_s / self.ambient_pressure_pa * (self.radius_m / self.clearance_m) ** 2

    @property
    def modified_gravity_m_s2(self) -> float:
        """``g + F_L / m``: gravity plus the static load per unit rotor mass."""
        return self.gravity_m_s2 + self.external_load_per_bearing_n / self.rotor_mass_per_bearing_kg

    @property
    def mass_parameter(self) -> float:
        """``M = p0 / (36 mu0^2 L) (C/R)^5 m``."""
        return (
            self.ambient_pressure_pa
            / (36.0 * self.viscosity_pa_s**2 * self.length_m)
            * (self.clearance_m / self.radius_m) ** 5
            * self.rotor_mass_per_bearing_kg
        )

    @property
    def gravity_parameter(self) -> float:
        """``G = 36 mu0^2 / (p0^2 R) (R/C)^5 (g + F_L/m)``."""
        return (
            36.0
            * self.viscosity_pa_s**2
            / (self.ambient_pressure_pa**2 * self.radius_m)
            * (self.radius_m / self.clearance_m) ** 5
            * self.modified_gravity_m_s2
        )

    @property
    def foil_stiffness(self) -> float:
        """Walowit-Anno foundation stiffness ``K_W = E_B C / [2(1-nu^2) p0 l_S] (t_B/l_B)^3``."""
        return (
            self.youngs_modulus_pa
            * self.clearance_m
            / (2.0 * (1.0 - self.poisson_ratio**2) * self.ambient_pressure_pa * self.bump_pitch_m)
            * (self.bump_foil_thickness_m / self.bump_half_width_m) ** 3
        )

    @property
    def kappa(self) -> float:
        """Geometry ratio ``kappa = R / L``."""
        return self.radius_m / self.length_m

    @property
    def bearing_number(self) -> float:
        """Bearing number ``Lambda`` at the nominal speed ``speed_rpm``."""
        return self.bearing_number_at(self.speed_rpm)

    @property
    def force_scale_n(self) -> float:
        """Force unit ``p0 R L`` in newtons."""
        return self.ambient_pressure_pa * self.radius_m * self.length_m

    def nondimensional(self, foil_stiffness: float | None = None) -> NondimensionalParameters:
        """The groups ``M, G, K_W, kappa`` (optionally overriding ``K_W``)."""
        return NondimensionalParameters(
            mass_parameter=self.mass_parameter,
            gravity_parameter=self.gravity_parameter,
            foil_stiffness=self.foil_stiffness if foil_stiffness is None else float(foil_stiffness),
            kappa=self.kappa,
        )

    # ----------------------------------------------------------------------------------------
    # conversions
    def bearing_number_at(self, speed_rpm: float) -> float:
        """``Lambda = omega0 T`` for a rotor speed in rpm."""
        if not math.isfinite(speed_rpm) or speed_rpm < 0:
            raise ValueError(f"speed_rpm must be finite and non-negative, got {speed_rpm!r}")
        return speed_rpm * _RPM_TO_RAD_S * self.time_scale_s

    def speed_rpm_at(self, bearing_number: float) -> float:
        """Rotor speed in rpm for a bearing number (inverse of :meth:`bearing_number_at`)."""
        if not math.isfinite(bearing_number) or bearing_number < 0:
            raise ValueError(f"bearing_number must be finite and non-negative, got {bearing_number!r}")
        return bearing_number / self.time_scale_s / _RPM_TO_RAD_S

    def seconds(self, tau: float) -> float:
        """Physical time in s for nondimensional time ``tau``."""
        return tau * self.time_scale_s

    def tau(self, seconds: float) -> float:
        """Nondimensional time for a physical time in s."""
        return seconds / self.time_scale_s

    def micrometres(self, length: float) -> float:
        """Physical length in um of a nondimensional length (eccentricity, film, deflection)."""
        return length * self.clearance_m * 1e6

    def newtons(self, force: float) -> float:
        """Physical force in N of a nondimensional bearing force."""
        return force * self.force_scale_n

    def pascals(self, pressure: float) -> float:
        """Physical absolute pressure in Pa of a nondimensional pressure ``P``."""
        return pressure * self.ambient_pressure_pa

    def frequency_hz(self, angular_frequency: float) -> float:
        """Physical frequency in Hz of a nondimensional angular frequency (rad per unit tau)."""
        return angular_frequency / (2.0 * math.pi * self.time_scale_s)

    def rate_rpm_per_s(self, bearing_number_rate: float) -> float:
        """Speed ramp in rpm/s of a bearing-number rate ``dLambda/dtau``."""
        return bearing_number_rate / self.time_scale_s**2 / _RPM_TO_RAD_S

    # ----------------------------------------------------------------------------------------
    # bearing files
    @classmethod
    def from_mapping(cls, data: Mapping[str, Any], source: str = "bearing") -> BearingParameters:
        """A bearing from a flat mapping of field names to numbers; missing fields take Table 1.

        Raises:
            ValueError: one line naming ``source`` and the offending key: an unknown key (with the
                nearest field name), a value that is not a number (strings, booleans, tables,
                arrays), or a value the constructor refuses (non-positive, ``C/R >= 0.02``, ...).
        """
        if not isinstance(data, Mapping):
            raise ValueError(f"{source}: must be a table of field = number, got {type(data).__name__}")
        names = [f.name for f in fields(cls)]
        for key, value in data.items():
            if isinstance(value, Mapping):
                raise ValueError(
                    f"{source}: [{key}] is a table; the keys must be flat at the top level (field = number)"
                )
            if key not in names:
                import difflib

                near = difflib.get_close_matches(str(key), names, n=1)
                hint = f" (did you mean {near[0]!r}?)" if near else f" (known keys: {', '.join(names)})"
                raise ValueError(f"{source}: unknown key {key!r}{hint}")
            if isinstance(value, bool) or not isinstance(value, (int, float)):
                raise ValueError(f"{source}: {key} must be a number, got {value!r}")
        values: dict[str, float | int] = {}
        for key, value in data.items():
            try:
                v = float(value)
            except OverflowError:
                raise ValueError(f"{source}: {key} is too large, got {value!r}") from None
            # bump_count = 26.0 is the integer 26; 26.5 stays a float and is refused below
            values[key] = int(v) if key == "bump_count" and v.is_integer() else v
        try:
            return cls(**values)
        except ValueError as exc:
            raise ValueError(f"{source}: {exc}") from None

    @classmethod
    def from_toml(cls, path: str | Path) -> BearingParameters:
        """A bearing from a TOML file of top-level ``field = number`` lines (the shipped ones are in
        ``gfb_env/data/bearings/``, see :func:`shipped_bearing_path`).

        Keys are the field names of this class (SI units as in their names); missing keys take
        Table 1.  An optional ``[friction]`` table (the frictional foil's inputs, see
        :class:`FrictionParameters` and :func:`read_bearing_file`) is validated and not part of the
        bearing.  Raises ``ValueError`` (one line naming the file and the key) for a missing or
        unreadable file, a device, pipe or socket, a file over :data:`MAX_BEARING_FILE_BYTES`, a TOML
        syntax error (nesting too deep included), an unknown key or a bad value."""
        return read_bearing_file(path)[0]

    def replace(self, **changes: float) -> BearingParameters:
        """A copy with some fields changed (validated again)."""
        return replace(self, **changes)

    def as_dict(self) -> dict[str, float]:
        """All dimensional fields as a plain dict."""
        return asdict(self)


def _read_toml(path: str | Path) -> dict[str, Any]:
    """The parsed TOML of a bearing file (size and type checked before reading; see
    :meth:`BearingParameters.from_toml` for what is refused)."""
    p = Path(path).expanduser()
    try:
        # O_NONBLOCK: opening a named pipe must not wait for a writer; fstat then refuses it
        fd = os.open(p, os.O_RDONLY | getattr(os, "O_NONBLOCK", 0))
    except FileNotFoundError:
        raise ValueError(f"{path}: no such file") from None
    except IsADirectoryError:
        raise ValueError(f"{path}: is a folder, not a bearing file") from None
    except OSError as exc:
        raise ValueError(f"{path}: cannot read ({exc.strerror})") from None
    st = os.fstat(fd)
    if stat.S_ISDIR(st.st_mode):
        os.close(fd)
        raise ValueError(f"{path}: is a folder, not a bearing file")
    with os.fdopen(fd, "rb") as fh:
        if not stat.S_ISREG(st.st_mode):
            raise ValueError(f"{path}: not a regular file (a device, pipe or socket), not a bearing file")
        if st.st_size > MAX_BEARING_FILE_BYTES:
            raise ValueError(
                f"{path}: {st.st_size} bytes, a bearing file has at most {MAX_BEARING_FILE_BYTES} bytes"
            )
        try:
            raw = fh.read(MAX_BEARING_FILE_BYTES + 1)  # +1: a file that grew since fstat
        except OSError as exc:
            raise ValueError(f"{path}: cannot read ({exc.strerror})") from None
    if len(raw) > MAX_BEARING_FILE_BYTES:
        raise ValueError(f"{path}: a bearing file has at most {MAX_BEARING_FILE_BYTES} bytes")
    try:
        text = raw.decode("utf-8")
    except UnicodeDecodeError:
        raise ValueError(f"{path}: not a UTF-8 text (TOML) file") from None
    try:
        data = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise ValueError(f"{path}: TOML syntax error: {str(exc).splitlines()[0]}") from None
    except RecursionError:  # tomllib recurses once per nesting level of an array or table
        raise ValueError(f"{path}: TOML syntax error: arrays or tables nested too deeply") from None
    return data


# ------------------------------------------------------------------------------------------------
# the frictional foil's physical inputs (issue 22)
@dataclass(frozen=True)
class FrictionParameters:
    """Physical inputs of the frictional foil (``--structure frictional``), the ``[friction]`` table of
    a bearing file.  Kept apart from :class:`BearingParameters` so that a bearing file without them
    has the same :meth:`BearingParameters.as_dict` (the key of the envs' task constants) as before.

    Attributes:
        friction_coefficient: Coulomb coefficient ``mu_C`` of the bump-foil contacts (dimensionless,
            finite, >= 0; identified bump-foil values are about 0.05-0.2).
        stick_stiffness_n_m3: stick stiffness ``k_T`` of the Jenkins element per unit foil area (N/m per
            m^2, as the foundation stiffness ``k_W`` behind K_W); nondimensional ``K_T = k_T C / p0``,
            the scaling of ``K_W = k_W C / p0`` (pressures by p0, deflections by C).
        stick_stiffness_ratio: ``K_T / K_W`` instead (dimensionless, > 0), relative to the model's K_W
            (the Walowit-Anno value or ``--foil-stiffness``).

    At most one of the two stiffness inputs; with neither, the model's default (K_T = K_W).
    """

    friction_coefficient: float = 0.1
    stick_stiffness_n_m3: float | None = None
    stick_stiffness_ratio: float | None = None

    def __post_init__(self) -> None:
        for f in fields(self):
            value = getattr(self, f.name)
            if value is None and f.name != "friction_coefficient":
                continue
            if isinstance(value, bool) or not isinstance(value, (int, float)):
                raise ValueError(f"friction.{f.name} must be a number, got {value!r}")
            if not math.isfinite(value):
                raise ValueError(f"friction.{f.name} must be finite, got {value!r}")
            if f.name == "friction_coefficient" and value < 0:
                raise ValueError(f"friction.{f.name} must be >= 0, got {value!r}")
            if f.name != "friction_coefficient" and value <= 0:
                raise ValueError(f"friction.{f.name} must be positive, got {value!r}")
            object.__setattr__(self, f.name, float(value))
        if self.stick_stiffness_n_m3 is not None and self.stick_stiffness_ratio is not None:
            raise ValueError(
                "friction.stick_stiffness_n_m3 and friction.stick_stiffness_ratio: give at most one of them"
            )

    def stick_stiffness(self, bearing: BearingParameters, foil_stiffness: float) -> float | None:
        """Nondimensional ``K_T`` for ``bearing`` and the model's ``K_W`` (None: not given)."""
        if self.stick_stiffness_n_m3 is not None:
            return self.stick_stiffness_n_m3 * bearing.clearance_m / bearing.ambient_pressure_pa
        if self.stick_stiffness_ratio is not None:
            return self.stick_stiffness_ratio * foil_stiffness
        return None

    @classmethod
    def from_mapping(cls, data: Mapping[str, Any], source: str = "bearing") -> FrictionParameters:
        """From the ``[friction]`` table's mapping; missing keys take the defaults.

        Raises:
            ValueError: one line naming ``source`` and ``friction.KEY``: an unknown key (with the
                nearest name) or a bad value."""
        if not isinstance(data, Mapping):
            raise ValueError(f"{source}: friction must be a table of key = number, got {type(data).__name__}")
        names = [f.name for f in fields(cls)]
        for key, value in data.items():
            if key not in names:
                import difflib

                near = difflib.get_close_matches(str(key), names, n=1)
                hint = f" (did you mean {near[0]!r}?)" if near else f" (known keys: {', '.join(names)})"
                raise ValueError(f"{source}: unknown key friction.{key}{hint}")
            if isinstance(value, bool) or not isinstance(value, (int, float)):
                raise ValueError(f"{source}: friction.{key} must be a number, got {value!r}")
        try:
            return cls(**{k: float(v) for k, v in data.items()})
        except OverflowError:
            raise ValueError(f"{source}: a friction value is too large") from None
        except ValueError as exc:
            raise ValueError(f"{source}: {exc}") from None


def read_bearing_file(path: str | Path) -> tuple[BearingParameters, FrictionParameters | None]:
    """The bearing of a TOML bearing file and its optional ``[friction]`` table (None without one).

    Raises ``ValueError`` (one line naming the file and the key) as :meth:`BearingParameters.from_toml`,
    and for a bad ``[friction]`` key or value (:meth:`FrictionParameters.from_mapping`)."""
    data = _read_toml(path)
    friction_table = data.pop("friction", None)
    bearing = BearingParameters.from_mapping(data, source=str(path))
    friction = (
        None if friction_table is None else FrictionParameters.from_mapping(friction_table, source=str(path))
    )
    return bearing, friction

"""Stability map (paper Fig. 4) and hysteresis map: computation by resumable sweeps, files, loaders.

* :func:`compute_stability_map`: ``Lambda_c(K_W, D_W)`` of the viscoelastic foil on a grid, the elastic
  curve ``Lambda_c(K_W)`` and the rigid value; the optimum damping ``D_W*(K_W) = argmax Lambda_c`` per
  stiffness (parabola through the best grid point and its neighbours in ``log D_W``).
* :func:`compute_hysteresis_map`: ``Lambda_c`` and the fold of cycles ``Lambda_fold`` over ``D_W`` for a few
  stiffnesses.  For ``Lambda < Lambda_fold`` only the equilibrium is stable, for
  ``Lambda_fold < Lambda < Lambda_c`` both the equilibrium and the whirl (bistable), above ``Lambda_c``
  only the whirl.
* :func:`load_hysteresis_map` / :func:`optimal_foil_damping` read the maps shipped with the package
  (``gfb_env/data/hysteresis_map.csv``, ``gfb_env/data/stability_map.csv``: copies of the committed
  ``results/hysteresis_map/hysteresis_map.csv`` and ``results/fig4_stability_map/stability_map.csv``,
  which ``tests/install/test_package_data.py`` keeps identical) or an explicit ``path``.  Library code never
  reads ``results/`` at run time: an installed package has no such folder.
"""

from __future__ import annotations

import csv
import math
import os
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from gfb_env.analysis.periodic import ShootingError, coast_down_fold, fold_bearing_number
from gfb_env.analysis.stability import NoCriticalPointError, NoStableEquilibriumError, critical_bearing_number
from gfb_env.model import GFBModel, Grid
from gfb_env.params import BearingParameters, check_positive
from gfb_env.sweeps import run_sweep

__all__ = [
    "HYSTERESIS_MAP_TASKS_CSV",
    "MAPS_DATA_DIR",
    "StabilityMap",
    "HysteresisMap",
    "critical_point_task",
    "hysteresis_task",
    "compute_stability_map",
    "write_stability_map",
    "plot_stability_map",
    "load_stability_map",
    "compute_hysteresis_map",
    "write_hysteresis_map",
    "load_hysteresis_map",
    "optimal_foil_damping",
]

#: Package data: the maps the agents and scripts read by default (see the module docstring).
MAPS_DATA_DIR = Path(__file__).resolve().parents[1] / "data"
STABILITY_MAP_CSV = "stability_map.csv"
HYSTERESIS_MAP_CSV = "hysteresis_map.csv"
#: The environments' nominal bearing on their 31x7 grid (``python -m gfb_experiments.hysteresis_map
#: --tasks``): the hysteresis band the benchmark's path figure draws.  Kept apart from the paper-grid
#: map so that the scripted agents, which read that one, are unchanged.
HYSTERESIS_MAP_TASKS_CSV = "hysteresis_map_tasks.csv"


def _cell(v):
    return "" if (v is None or (isinstance(v, float) and not math.isfinite(v))) else v


def _nan(x):
    return math.nan if x is None else float(x)


# ------------------------------------------------------------------------------------------------
def critical_point_task(
    structure: str,
    foil_stiffness: float,
    foil_damping: float,
    grid: str = "79x7",
    bearing_min: float = 0.1,
    bearing_max: float = 3.0,
    scan_step: float = 0.05,
    bearing: dict | None = None,
) -> dict:
    """One map point: ``Lambda_c`` and its status (``ok``, ``no_stable_equilibrium``, ``stable_in_range``).

    ``bearing``: the fields of a :class:`~gfb_env.params.BearingParameters` (None: Table 1)."""
    bp = None if bearing is None else BearingParameters.from_mapping(bearing)
    model = GFBModel(structure, Grid.parse(grid), bearing=bp, foil_stiffness=foil_stiffness)
    try:
        cp = critical_bearing_number(model, foil_damping, (bearing_min, bearing_max), scan_step)
    except NoStableEquilibriumError as exc:
        return {"status": "no_stable_equilibrium", "critical_bearing_number": math.nan, "message": str(exc)}
    except NoCriticalPointError as exc:
        return {"status": "stable_in_range", "critical_bearing_number": math.nan, "message": str(exc)}
    d = cp.as_dict()
    d["status"] = "ok"
    return d


@dataclass
class StabilityMap:
    """Fig. 4 data.

    Attributes:
        foil_stiffness: ``K_W`` grid, shape ``(nk,)``; foil_damping: ``D_W`` grid, ``(nd,)``.
        viscoelastic: ``Lambda_c`` of the viscoelastic foil, ``(nk, nd)`` (NaN: no stable equilibrium or
            stable in the scanned range, see ``status``).
        elastic: ``Lambda_c`` of the elastic foil per ``K_W``; rigid: the rigid value.
        optimum_damping, optimum_critical: ``D_W*`` and ``max_D Lambda_c`` per ``K_W``.
        records: the raw sweep records.
    """

    foil_stiffness: np.ndarray
    foil_damping: np.ndarray
    viscoelastic: np.ndarray
    elastic: np.ndarray
    rigid: float
    optimum_damping: np.ndarray
    optimum_critical: np.ndarray
    grid: str
    records: list


def optimum_from_curve(dws: np.ndarray, lc: np.ndarray) -> tuple[float, float]:
    """Optimum damping ``D_W*`` and ``max Lambda_c`` of a sampled curve ``Lambda_c(D_W)``: the vertex of
    the parabola in ``log D_W`` through the best sample and its neighbours (the best sample itself at
    the ends of the range or where the parabola opens upwards; NaN if no sample is finite)."""
    dws, lc = np.asarray(dws, dtype=float), np.asarray(lc, dtype=float)
    ok = np.isfinite(lc)
    if not ok.any():
        return math.nan, math.nan
    j = int(np.nanargmax(np.where(ok, lc, -np.inf)))
    if 0 < j < len(dws) - 1 and ok[j - 1] and ok[j + 1]:
        x = np.log(dws[j - 1 : j + 2])
        c = np.polyfit(x, lc[j - 1 : j + 2], 2)
        if c[0] < 0:
            xv = -c[1] / (2 * c[0])
            return float(np.exp(xv)), float(np.polyval(c, xv))
    return float(dws[j]), float(lc[j])


def compute_stability_map(
    foil_stiffness: np.ndarray | list[float],
    foil_damping: np.ndarray | list[float],
    grid: str = "79x7",
    n_jobs: int = 1,
    scheduler=None,
    checkpoint: str | os.PathLike | None = None,
    progress: bool = True,
    scan_step: float = 0.05,
    bearing_max: float = 3.0,
    bearing: BearingParameters | None = None,
) -> StabilityMap:
    """``Lambda_c`` over ``K_W x D_W`` (viscoelastic), over ``K_W`` (elastic) and the rigid value, by
    :func:`gfb_env.sweeps.run_sweep` (parallel, resumable).  ``bearing`` (default Table 1) sets M, G,
    kappa and the rpm scale; it is part of each sweep point (and so of the checkpoint key) only when
    given, so Table-1 checkpoints stay valid."""
    kws = np.asarray(foil_stiffness, dtype=float)
    dws = np.asarray(foil_damping, dtype=float)
    if kws.size == 0 or np.any(~np.isfinite(kws)) or np.any(kws <= 0):
        raise ValueError("foil_stiffness must be a non-empty list of positive numbers")
    if dws.size == 0 or np.any(~np.isfinite(dws)) or np.any(dws <= 0):
        raise ValueError("foil_damping must be a non-empty list of positive numbers")
    Grid.parse(grid)
    common = {"grid": grid, "scan_step": scan_step, "bearing_max": bearing_max}
    if bearing is not None:
        common["bearing"] = bearing.as_dict()
    pts = [{"structure": "rigid", "foil_stiffness": 1.0, "foil_damping": 1.0, **common}]
    pts += [{"structure": "elastic", "foil_stiffness": float(k), "foil_damping": 1.0, **common} for k in kws]
    pts += [
        {"structure": "viscoelastic", "foil_stiffness": float(k), "foil_damping": float(d), **common}
        for k in kws
        for d in dws
    ]
    recs = run_sweep(
        critical_point_task,
        pts,
        checkpoint,
        n_jobs=n_jobs,
        scheduler=scheduler,
        progress=progress,
        desc="stability map",
    )

    def lc(rec):
        return _nan(rec["result"]["critical_bearing_number"]) if rec["result"] else math.nan

    rigid = lc(recs[0])
    elastic = np.array([lc(r) for r in recs[1 : 1 + len(kws)]])
    visco = np.array([lc(r) for r in recs[1 + len(kws) :]]).reshape(len(kws), len(dws))
    opt = np.array([optimum_from_curve(dws, visco[i]) for i in range(len(kws))]).reshape(len(kws), 2)
    return StabilityMap(kws, dws, visco, elastic, rigid, opt[:, 0], opt[:, 1], grid, recs)


_MAP_FIELDS = [
    "structure",
    "foil_stiffness",
    "foil_damping",
    "critical_bearing_number",
    "critical_speed_rpm",
    "whirl_frequency_ratio",
    "eccentricity_at_onset",
    "crossing_speed",
    "status",
    "grid",
]


def write_stability_map(smap: StabilityMap, out_dir: str | os.PathLike) -> dict[str, Path]:
    """Write ``stability_map.csv`` (long format, one row per configuration), ``optimum_damping.csv`` and
    ``stability_map.png`` into ``out_dir``; returns the paths."""
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    p_csv = out / "stability_map.csv"
    with p_csv.open("w", newline="") as fh:
        w = csv.DictWriter(fh, fieldnames=_MAP_FIELDS, extrasaction="ignore")
        w.writeheader()
        for rec in smap.records:
            row = dict(rec["point"])
            row.update(rec["result"] or {"status": "error", "critical_bearing_number": math.nan})
            if row["structure"] != "viscoelastic":
                row["foil_damping"] = ""
            if row["structure"] == "rigid":
                row["foil_stiffness"] = ""
            w.writerow({k: _cell(v) for k, v in row.items()})
    p_opt = out / "optimum_damping.csv"
    with p_opt.open("w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(
            [
                "foil_stiffness",
                "optimum_foil_damping",
                "max_critical_bearing_number",
                "elastic_critical_bearing_number",
                "rigid_critical_bearing_number",
            ]
        )
        for k, d, l, e in zip(smap.foil_stiffness, smap.optimum_damping, smap.optimum_critical, smap.elastic):
            w.writerow([k, d, l, e, smap.rigid])
    p_png = out / "stability_map.png"
    plot_stability_map(smap, p_png)
    return {"csv": p_csv, "optimum": p_opt, "png": p_png}


def plot_stability_map(smap: StabilityMap, path: str | os.PathLike) -> None:
    """Heat map of ``Lambda_c(K_W, D_W)`` (viscoelastic) with ``D_W*`` marked, and the elastic/rigid
    curves against ``K_W`` beside it (the paper's Fig. 4 as two 2-D panels)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, (a1, a2) = plt.subplots(1, 2, figsize=(12, 4.8), constrained_layout=True)
    K, D = smap.foil_stiffness, smap.foil_damping
    Z = np.ma.masked_invalid(smap.viscoelastic.T)
    if len(K) > 1 and len(D) > 1:
        pc = a1.pcolormesh(K, D, Z, shading="gouraud", cmap="viridis")
        a1.set_xlim(K.min(), K.max())
        fig.colorbar(pc, ax=a1, label=r"critical bearing number $\Lambda_c$")
        cs = a1.contour(K, D, Z, colors="w", linewidths=0.6, levels=8)
        a1.clabel(cs, fontsize=7, fmt="%.2f")
    else:
        a1.scatter(np.repeat(K, len(D)), np.tile(D, len(K)), c=smap.viscoelastic.ravel())
    a1.plot(K, smap.optimum_damping, "r-o", ms=4, label=r"optimum $D_W^*$ (max $\Lambda_c$)")
    a1.set_xscale("log")
    a1.set_yscale("log")
    a1.set_xlabel(r"foil stiffness $K_W$")
    a1.set_ylabel(r"foil damping $D_W$")
    a1.set_title(f"viscoelastic foil, grid {smap.grid}")
    a1.legend(loc="upper left", fontsize=8)
    a2.plot(K, smap.optimum_critical, "r-o", ms=4, label=r"viscoelastic, $\max_{D_W}\Lambda_c$")
    for j in np.linspace(0, len(D) - 1, min(4, len(D))).astype(int):
        a2.plot(K, smap.viscoelastic[:, j], "-", lw=0.8, alpha=0.7, label=f"viscoelastic, $D_W$={D[j]:.3g}")
    a2.plot(K, smap.elastic, "k-.", lw=1.5, label="elastic")
    a2.axhline(smap.rigid, color="grey", lw=2, alpha=0.6, label=f"rigid ({smap.rigid:.4f})")
    a2.set_xscale("log")
    a2.set_xlabel(r"foil stiffness $K_W$")
    a2.set_ylabel(r"$\Lambda_c$")
    a2.set_title("critical bearing number vs stiffness")
    a2.legend(fontsize=7)
    a2.grid(alpha=0.3)
    fig.savefig(path, dpi=120)
    plt.close(fig)


def load_stability_map(path: str | os.PathLike | None = None) -> dict[str, np.ndarray]:
    """Read ``stability_map.csv``: arrays ``structure``, ``foil_stiffness``, ``foil_damping``,
    ``critical_bearing_number`` (NaN where empty)."""
    p = Path(path) if path is not None else MAPS_DATA_DIR / STABILITY_MAP_CSV
    if not p.exists():
        raise FileNotFoundError(
            f"no stability map at {p}; it is made by `python -m gfb_experiments.fig4_stability_map` "
            "(results/fig4_stability_map/stability_map.csv, shipped as gfb_env/data/stability_map.csv)"
        )
    rows = list(csv.DictReader(p.open()))
    if not rows:
        raise ValueError(f"stability map {p} is empty")

    def f(x):
        return float(x) if x not in ("", None) else math.nan

    return {
        "structure": np.array([r["structure"] for r in rows]),
        "foil_stiffness": np.array([f(r["foil_stiffness"]) for r in rows]),
        "foil_damping": np.array([f(r["foil_damping"]) for r in rows]),
        "critical_bearing_number": np.array([f(r["critical_bearing_number"]) for r in rows]),
    }


def optimal_foil_damping(foil_stiffness: float, path: str | os.PathLike | None = None) -> float:
    """Optimum damping ``D_W*`` maximising ``Lambda_c`` at ``K_W = foil_stiffness``, from the stability
    map shipped with the package or at ``path`` (per-stiffness parabola in ``log D_W``, then linear
    interpolation in ``log K_W``; clamped to the map's ``K_W`` range)."""
    k = check_positive("foil_stiffness", foil_stiffness)
    m = load_stability_map(path)
    sel = m["structure"] == "viscoelastic"
    kws = np.unique(m["foil_stiffness"][sel])
    dopt = []
    for kw in kws:
        s = sel & (m["foil_stiffness"] == kw)
        order = np.argsort(m["foil_damping"][s])
        dopt.append(
            optimum_from_curve(m["foil_damping"][s][order], m["critical_bearing_number"][s][order])[0]
        )
    dopt = np.array(dopt)
    ok = np.isfinite(dopt)
    if not ok.any():
        raise ValueError("the stability map has no finite critical bearing number")
    return float(np.exp(np.interp(np.log(k), np.log(kws[ok]), np.log(dopt[ok]))))


# ------------------------------------------------------------------------------------------------
def hysteresis_task(
    foil_stiffness: float,
    foil_damping: float,
    structure: str = "viscoelastic",
    grid: str = "79x7",
    n_steps: int = 300,
    coast_down: bool = False,
    max_points: int | None = None,
    start: str = "hopf",
) -> dict:
    """One hysteresis-map point: ``Lambda_c``, ``Lambda_fold`` (shooting + continuation from the Hopf
    point, or from the developed whirl with ``start="whirl"``: see
    :func:`~gfb_env.analysis.periodic.fold_bearing_number`), the limit-cycle amplitude at ``Lambda_c``
    and optionally the coast-down estimate."""
    model = GFBModel(structure, Grid.parse(grid), foil_stiffness=foil_stiffness)
    cp = critical_bearing_number(model, foil_damping)
    out = cp.as_dict()
    out.update(
        {
            "fold_bearing_number": math.nan,
            "limit_cycle_amplitude_at_critical": math.nan,
            "limit_cycle_max_eccentricity_at_critical": math.nan,
            "whirl_period_at_critical": math.nan,
            "contact_bearing_number": math.nan,
            "band_lower_bearing_number": math.nan,
            "fold_message": "",
        }
    )
    try:
        fr = fold_bearing_number(
            model,
            foil_damping,
            critical=cp.critical_bearing_number,
            n_steps=n_steps,
            max_points=max_points,
            start=start,
        )
        out.update(
            {
                "fold_bearing_number": _nan(fr.fold_bearing_number),
                "limit_cycle_amplitude_at_critical": fr.amplitude_at_critical,
                "limit_cycle_max_eccentricity_at_critical": fr.max_eccentricity_at_critical,
                "whirl_period_at_critical": fr.period_at_critical,
                "contact_bearing_number": _nan(fr.contact_bearing_number),
                "band_lower_bearing_number": fr.band_lower_bearing_number,
                "fold_message": fr.message,
                "branch_bearing_number": fr.branch.bearing_number.tolist(),
                "branch_amplitude": fr.branch.amplitude.tolist(),
                "branch_stable": [o.stable for o in fr.branch.orbits],
            }
        )
    except ShootingError as exc:
        out["fold_message"] = f"shooting failed: {exc}"
    if coast_down:
        try:
            cd = coast_down_fold(model, foil_damping, cp.critical_bearing_number + 0.01)
            out["coast_down_fold_bearing_number"] = _nan(cd.fold_bearing_number)
        except ShootingError as exc:
            out["coast_down_fold_bearing_number"] = math.nan
            out["fold_message"] += f"; coast-down failed: {exc}"
    return out


@dataclass
class HysteresisMap:
    """Arrays (one entry per configuration) of the hysteresis map."""

    foil_stiffness: np.ndarray
    foil_damping: np.ndarray
    critical_bearing_number: np.ndarray
    fold_bearing_number: np.ndarray
    limit_cycle_amplitude_at_critical: np.ndarray
    coast_down_fold_bearing_number: np.ndarray
    band_lower_bearing_number: np.ndarray | None = None  # NaN where the map predates the column
    grid: np.ndarray | None = None  # the grid of each row ("" where the map lacks the column)

    def region(self, foil_stiffness: float, foil_damping: float, bearing_number: float) -> str:
        """``"stable"``, ``"bistable"`` or ``"whirl"`` at the nearest mapped ``(K_W, D_W)`` (interpolated
        in ``log D_W`` along the nearest ``K_W``)."""
        lc, lf = self.bounds(foil_stiffness, foil_damping)
        if bearing_number >= lc:
            return "whirl"
        if math.isfinite(lf) and bearing_number >= lf:
            return "bistable"
        return "stable"

    def band_lower(self, foil_stiffness: float, foil_damping: float) -> float:
        """Lower edge of the hysteresis band (``band_lower_bearing_number``: the fold, or where the
        unstable cycles reach contact, or ``Lambda_c`` where there is no band) interpolated in
        ``log D_W`` at the nearest mapped ``K_W`` (clamped to the mapped dampings); NaN where the map
        lacks the column."""
        if self.band_lower_bearing_number is None:
            return math.nan
        kws = np.unique(self.foil_stiffness)
        kw = kws[np.argmin(np.abs(np.log(kws) - math.log(foil_stiffness)))]
        s = (self.foil_stiffness == kw) & np.isfinite(self.band_lower_bearing_number)
        if not s.any():
            return math.nan
        order = np.argsort(self.foil_damping[s])
        x = np.log(self.foil_damping[s][order])
        return float(np.interp(math.log(foil_damping), x, self.band_lower_bearing_number[s][order]))

    def bounds(self, foil_stiffness: float, foil_damping: float) -> tuple[float, float]:
        """``(Lambda_c, Lambda_fold)`` interpolated in ``log D_W`` at the nearest mapped ``K_W``."""
        kws = np.unique(self.foil_stiffness)
        kw = kws[np.argmin(np.abs(np.log(kws) - math.log(foil_stiffness)))]
        s = self.foil_stiffness == kw
        order = np.argsort(self.foil_damping[s])
        x = np.log(self.foil_damping[s][order])
        lc = float(np.interp(math.log(foil_damping), x, self.critical_bearing_number[s][order]))
        f = self.fold_bearing_number[s][order]
        ok = np.isfinite(f)
        lf = float(np.interp(math.log(foil_damping), x[ok], f[ok])) if ok.any() else math.nan
        return lc, lf


_HYST_FIELDS = [
    "foil_stiffness",
    "foil_damping",
    "critical_bearing_number",
    "fold_bearing_number",
    "limit_cycle_amplitude_at_critical",
    "limit_cycle_max_eccentricity_at_critical",
    "whirl_period_at_critical",
    "whirl_frequency_ratio",
    "coast_down_fold_bearing_number",
    "structure",
    "grid",
    "fold_message",
    "contact_bearing_number",
    "band_lower_bearing_number",
]


def compute_hysteresis_map(
    foil_stiffness: list[float],
    foil_damping: list[float],
    grid: str = "79x7",
    n_steps: int = 300,
    coast_down_points: set | None = None,
    n_jobs: int = 1,
    scheduler=None,
    checkpoint: str | os.PathLike | None = None,
    progress: bool = True,
) -> list[dict]:
    """Sweep :func:`hysteresis_task` over ``K_W x D_W``; ``coast_down_points`` is a set of ``(K_W, D_W)``
    that also get the coast-down cross-check.  Returns flat records (point + result)."""
    cd = coast_down_points or set()
    pts = [
        {
            "foil_stiffness": float(k),
            "foil_damping": float(d),
            "grid": grid,
            "n_steps": int(n_steps),
            "coast_down": (float(k), float(d)) in cd,
        }
        for k in foil_stiffness
        for d in foil_damping
    ]
    recs = run_sweep(
        hysteresis_task,
        pts,
        checkpoint,
        n_jobs=n_jobs,
        scheduler=scheduler,
        progress=progress,
        desc="hysteresis map",
    )
    rows = []
    for r in recs:
        row = dict(r["point"])
        row.update(r["result"] or {"fold_message": f"error: {r['error']}"})
        rows.append(row)
    return rows


def write_hysteresis_map(rows: list[dict], out_dir: str | os.PathLike) -> Path:
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    p = out / "hysteresis_map.csv"
    with p.open("w", newline="") as fh:
        w = csv.DictWriter(fh, fieldnames=_HYST_FIELDS, extrasaction="ignore")
        w.writeheader()
        for row in rows:
            w.writerow(
                {
                    k: ("" if (v is None or (isinstance(v, float) and not math.isfinite(v))) else v)
                    for k, v in row.items()
                }
            )
    return p


def load_hysteresis_map(path: str | os.PathLike | None = None) -> HysteresisMap:
    """Read the shipped hysteresis map (``gfb_env/data/hysteresis_map.csv``) or ``path`` into arrays
    (NaN where empty)."""
    p = Path(path) if path is not None else MAPS_DATA_DIR / HYSTERESIS_MAP_CSV
    if not p.exists():
        raise FileNotFoundError(
            f"no hysteresis map at {p}; it is made by `python -m gfb_experiments.hysteresis_map` "
            "(results/hysteresis_map/hysteresis_map.csv, shipped as gfb_env/data/hysteresis_map.csv)"
        )
    rows = list(csv.DictReader(p.open()))
    if not rows:
        raise ValueError(f"hysteresis map {p} is empty")

    def col(name):
        return np.array([float(r[name]) if r.get(name) not in ("", None) else math.nan for r in rows])

    return HysteresisMap(
        foil_stiffness=col("foil_stiffness"),
        foil_damping=col("foil_damping"),
        critical_bearing_number=col("critical_bearing_number"),
        fold_bearing_number=col("fold_bearing_number"),
        limit_cycle_amplitude_at_critical=col("limit_cycle_amplitude_at_critical"),
        coast_down_fold_bearing_number=col("coast_down_fold_bearing_number"),
        band_lower_bearing_number=col("band_lower_bearing_number"),
        grid=np.array([r.get("grid") or "" for r in rows]),
    )

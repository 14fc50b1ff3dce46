"""A documented grid search of training hyperparameters, scored on the VALIDATION seeds only (issue 21).

The library half of ``python -m gfb_experiments.tune`` (:mod:`gfb_experiments.tune`).  A grid such as
``"learning_rate=lin_3e-4,lin_1e-3;n_epochs=5,10"`` (``;`` between hyperparameters, ``,`` between values;
commas inside brackets belong to the value, so ``policy_kwargs=dict(net_arch=[64, 64])`` is one value) is
the Cartesian product of its values (4 points here).  Every point is a full training run per training seed
through :func:`gfb_agents.learned.train.train` (checkpoints, resume, validation, ``best/``), with the
point's values overriding the entry of the base YAML: the merged entry is written to
``<out>/<point>/hyperparams.yml`` and the runs of the point live in ``<out>/<point>/seed<r>``, so a point
is reproduced by ``python -m gfb_experiments.train --hyperparams <out>/<point>/hyperparams.yml`` and the
training code is unchanged.  Rerunning the same search continues unfinished runs from their checkpoints
and skips finished ones (``train``'s own resume); a point folder whose YAML differs (another base file) is
refused.

Scoring reads each run's ``validation.json`` (the first ``eval_episodes`` VALIDATION seeds, played by the
training run itself; :func:`score_run` refuses a run whose validation seeds leave the VALIDATION range or
touch TEST): per point the mean over its training seeds of the best validation mean return (what
``best/``, the benchmarked model, scored), of the last validation's (the final policy) and of their
success rates.  :data:`RULES` name the choice: ``"best"`` (default) maximises the mean best validation
mean return, ``"final"`` the mean last one; ties go to the other score, then to the earlier point.  The
best-of-history score is optimistic (a maximum over noisy validations), equally for every point of the
same budget and ``eval_freq``; the final score is not.  The TEST seeds are never played here.
"""

from __future__ import annotations

import csv
import itertools
import json
import re
import tempfile
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import yaml

from gfb_agents.learned import train as train_mod
from gfb_agents.learned.evaluate import algo_class
from gfb_agents.learned.train import TrainConfig, load_hyperparams
from gfb_agents.seeds import TEST, VALIDATION

__all__ = [
    "RULES",
    "GridPoint",
    "TuneConfig",
    "parse_grid",
    "grid_points",
    "check_tune",
    "score_run",
    "choose_point",
    "run_tune",
]

#: how the point is chosen: the key of the per-point score maximised (the other breaks ties)
RULES = {"best": "mean_best_return", "final": "mean_final_return"}
#: zoo keys a grid may vary besides the algorithm's keyword arguments (``n_timesteps`` is ``timesteps``)
GRID_ZOO_KEYS = ("n_envs", "normalize", "policy")
#: keyword arguments the training command sets itself (refused by ``train`` too)
_OWN_KWARGS = ("self", "env", "seed", "device", "verbose", "tensorboard_log", "policy")
#: characters kept in a point's folder name
_SAFE = re.compile(r"[^A-Za-z0-9._=+,-]")


def _split_top(text: str, sep: str) -> list[str]:
    """``text`` split at ``sep`` outside brackets (``()[]{}``) and quotes."""
    parts, depth, quote, cur = [], 0, None, []
    for ch in text:
        if quote:
            quote = None if ch == quote else quote
        elif ch in "'\"":
            quote = ch
        elif ch in "([{":
            depth += 1
        elif ch in ")]}":
            depth -= 1
        elif ch == sep and depth == 0:
            parts.append("".join(cur))
            cur = []
            continue
        cur.append(ch)
    if depth != 0 or quote:
        raise ValueError(f"--grid: unbalanced brackets or quotes in {text!r}")
    parts.append("".join(cur))
    return parts


def _parse_value(text: str) -> Any:
    """A grid value: an int, a float, ``true`` / ``false``, else the string (``lin_3e-4``, a
    ``dict(...)`` policy_kwargs), as the YAML would hold it.  Not YAML's own reader: it reads ``3e-4``
    as a string."""
    t = text.strip()
    if re.fullmatch(r"[+-]?\d+", t):
        return int(t)
    try:
        return float(t)
    except ValueError:
        pass
    if t.lower() in ("true", "false"):
        return t.lower() == "true"
    return t


def parse_grid(text: str) -> dict[str, list[Any]]:
    """``"a=1,2;b=x"`` -> ``{"a": [1, 2], "b": ["x"]}`` (ValueError naming ``--grid`` if malformed or
    empty, a name or value repeated, a value empty)."""
    if not isinstance(text, str) or not text.strip():
        raise ValueError("--grid is empty: give e.g. 'learning_rate=lin_3e-4,lin_1e-3;n_epochs=5,10'")
    grid: dict[str, list[Any]] = {}
    for part in _split_top(text, ";"):
        if not part.strip():
            continue  # a trailing ';'
        name, eq, values = part.partition("=")
        name = name.strip()
        if not eq or not re.fullmatch(r"[A-Za-z_][A-Za-z0-9_]*", name):
            raise ValueError(f"--grid: {part.strip()!r} is not NAME=VALUE[,VALUE...]")
        if name in grid:
            raise ValueError(f"--grid: {name} is given twice")
        raw = _split_top(values, ",")
        if any(not v.strip() for v in raw):
            raise ValueError(f"--grid: {name} has an empty value in {values.strip()!r}")
        vals = [_parse_value(v) for v in raw]
        if len({json.dumps(v) for v in vals}) != len(vals):
            raise ValueError(f"--grid: {name} repeats a value in {values.strip()!r}")
        grid[name] = vals
    if not grid:
        raise ValueError(f"--grid is empty: {text!r}")
    return grid


@dataclass(frozen=True)
class GridPoint:
    """One point of the grid: its position in the product and its values (in the grid's order)."""

    index: int
    settings: dict[str, Any]

    @property
    def name(self) -> str:
        """The point's folder: ``learning_rate=lin_3e-4,n_epochs=5`` (characters outside
        ``[A-Za-z0-9._=+,-]`` become ``_`` and a short hash of the settings is appended, so names
        stay distinct)."""
        plain = ",".join(f"{k}={v}" for k, v in self.settings.items())
        if not _SAFE.search(plain) and len(plain) <= 100:
            return plain
        import hashlib

        return (
            _SAFE.sub("_", plain)[:80]
            + "-"
            + hashlib.sha1(json.dumps(self.settings).encode()).hexdigest()[:8]
        )


def grid_points(grid: dict[str, list[Any]]) -> list[GridPoint]:
    """The Cartesian product of the grid, the last name varying fastest."""
    names = list(grid)
    return [
        GridPoint(i, dict(zip(names, vals, strict=True)))
        for i, vals in enumerate(itertools.product(*(grid[n] for n in names)))
    ]


@dataclass(frozen=True)
class TuneConfig:
    """A grid search, validated when made.

    Attributes:
        base: the training run every point starts from (algo, env, frame stack, timesteps, eval
            episodes ...; its ``hyperparams`` is the base YAML, its ``out`` and ``seed`` are ignored).
        grid: name -> values (:func:`parse_grid`); names are keyword arguments of the algorithm or
            :data:`GRID_ZOO_KEYS`.
        seeds: the training seeds of every point.
        out: the search's folder.
        rule: a key of :data:`RULES`.
    """

    base: TrainConfig
    grid: dict[str, list[Any]]
    seeds: tuple[int, ...]
    out: Path
    rule: str = "best"
    points: tuple[GridPoint, ...] = field(init=False)

    def __post_init__(self) -> None:
        if not isinstance(self.grid, dict) or not self.grid or any(not v for v in self.grid.values()):
            raise ValueError(f"--grid is empty: {self.grid!r}")
        if self.base.timesteps is None:
            raise ValueError("--timesteps: a search needs its budget per run (a positive integer)")
        if not self.seeds:
            raise ValueError("--seeds: no training seed")
        if self.rule not in RULES:
            raise ValueError(f"--rule must be one of {sorted(RULES)}, got {self.rule!r}")
        params = _algo_params(self.base.algo)
        for name in self.grid:
            if name == "n_timesteps":
                raise ValueError("--grid: n_timesteps is the budget, set by --timesteps")
            if name in _OWN_KWARGS and name not in GRID_ZOO_KEYS:
                raise ValueError(f"--grid: {name} is set by the training command")
            if name not in params and name not in GRID_ZOO_KEYS:
                raise ValueError(
                    f"--grid: unknown hyperparameter {name!r}: not a keyword argument of "
                    f"{algo_class(self.base.algo).__name__} (nor one of {list(GRID_ZOO_KEYS)})"
                )
        if "n_envs" in self.grid and self.base.n_envs is not None:
            raise ValueError("--grid: n_envs is varied by the grid; drop --n-envs")
        object.__setattr__(self, "out", Path(self.out))
        object.__setattr__(self, "seeds", tuple(int(s) for s in self.seeds))
        object.__setattr__(self, "points", tuple(grid_points(self.grid)))

    def point_dir(self, p: GridPoint) -> Path:
        return self.out / p.name

    def point_yaml(self, p: GridPoint) -> Path:
        return self.point_dir(p) / "hyperparams.yml"

    def point_hyperparams(self, p: GridPoint) -> dict[str, Any]:
        """The base YAML's entry with the point's values and ``n_timesteps`` the search's budget (so
        ``python -m gfb_experiments.train --hyperparams <point>/hyperparams.yml`` reproduces a run)."""
        hp = load_hyperparams(self.base.algo, self.base.env_id, self.base.hyperparams)
        return {**hp, **p.settings, "n_timesteps": self.base.timesteps}

    def run_config(self, p: GridPoint, seed: int) -> TrainConfig:
        return TrainConfig(
            **{
                **self.base.as_dict(),
                "seed": int(seed),
                "out": self.point_dir(p) / f"seed{seed}",
                "hyperparams": self.point_yaml(p),
            }
        )


def _algo_params(algo: str) -> set[str]:
    import inspect

    return set(inspect.signature(algo_class(algo).__init__).parameters)


def _yaml_text(c: TuneConfig, p: GridPoint) -> str:
    head = (
        f"# grid point {p.index} of the search in {c.out} (python -m gfb_experiments.tune): the base "
        f"entry of {c.base.hyperparams or 'agents/hyperparams/' + c.base.algo + '.yml'} with "
        f"{json.dumps(p.settings)}\n"
    )
    return head + yaml.safe_dump({c.base.env_id: c.point_hyperparams(p)}, sort_keys=False)


def _entry(path: Path, c: TuneConfig) -> Any:
    """A point YAML's entry without ``n_timesteps`` (a rerun may extend the budget: ``train`` continues
    the finished runs)."""
    try:
        entry = (yaml.safe_load(path.read_text()) or {}).get(c.base.env_id)
    except (yaml.YAMLError, OSError, UnicodeDecodeError, AttributeError):
        return None
    return {k: v for k, v in entry.items() if k != "n_timesteps"} if isinstance(entry, dict) else None


def check_tune(c: TuneConfig, scheduler: str | None = None) -> None:
    """Refuse (ValueError, one line) what would make a run of the search fail after it started, writing
    nothing: every point's merged hyperparameters (values the algorithm or the zoo conventions reject),
    a point folder holding other hyperparameters or a run with other settings, the env kwargs, the output
    folder, the Dask scheduler (:func:`gfb_agents.learned.train.check_runs`, point by point)."""
    from gfb_env.scripting import check_output_dir
    from gfb_env.sweeps import check_scheduler

    with tempfile.TemporaryDirectory() as tmp:
        for p in c.points:
            y = Path(tmp) / f"p{p.index}.yml"
            y.write_text(_yaml_text(c, p))
            probe = TrainConfig(**{**c.base.as_dict(), "hyperparams": y, "out": None})
            try:
                *_, n_envs = train_mod._run_plan(probe)
            except ValueError as exc:
                raise ValueError(f"--grid point {json.dumps(p.settings)}: {exc}") from None
            have = c.point_yaml(p)
            if have.is_file() and _entry(have, c) != _entry(y, c):
                raise ValueError(
                    f"--out {c.out}: {have} holds other hyperparameters for this point (another base "
                    f"YAML?); use another --out"
                )
            for r in c.seeds:
                train_mod._check_same_settings(c.run_config(p, r), n_envs)
    train_mod._check_env_kwargs(c.base)
    if scheduler is not None:
        check_scheduler(scheduler)
    check_output_dir(str(c.out), "--out")


def score_run(run_dir: str | Path) -> dict[str, Any]:
    """The validation scores of one finished run from its ``validation.json`` and ``run.json``: best and
    last validation mean return and success rate, steps, wall time, throughput.

    Raises:
        RuntimeError: the run was validated on a seed outside VALIDATION (or inside TEST): its score
            may not choose hyperparameters.
    """
    d = Path(run_dir)
    val = json.loads((d / "validation.json").read_text())
    seeds = [int(s) for s in val.get("seeds", [])]
    if not seeds or any(s not in VALIDATION or s in TEST for s in seeds):
        raise RuntimeError(f"{d}: validated on seeds outside the VALIDATION range; not a tuning score")
    hist = val.get("history") or []
    if not hist or val.get("best") is None:
        raise RuntimeError(f"{d}: no validation recorded")
    best, final = val["best"], hist[-1]  # history is in the order played: the last is the final policy
    run = json.loads((d / "run.json").read_text())
    return {
        "timesteps": int(run["timesteps"]),
        "best_mean_return": float(best["mean_return"]),
        "best_timesteps": int(best["timesteps"]),
        "best_success_rate": float(best["success_rate"]),
        "final_mean_return": float(final["mean_return"]),
        "final_timesteps": int(final["timesteps"]),
        "final_success_rate": float(final["success_rate"]),
        "validation_episodes": len(seeds),
        "validation_seeds": f"{min(seeds)}-{max(seeds)}",
        "wall_time_s": float(run["wall_time_s"]),
        "env_steps_per_s": float(run["env_steps_per_s"]),
    }


def _mean(xs: list[float]) -> float | None:
    return sum(xs) / len(xs) if xs else None


def choose_point(summaries: list[dict[str, Any]], rule: str) -> dict[str, Any] | None:
    """The point of ``summaries`` (per-point records of :func:`run_tune`, complete ones only: every
    seed scored) maximising ``RULES[rule]``, ties to the other score, then to the earlier point."""
    key = RULES[rule]
    other = next(v for v in RULES.values() if v != key)
    ok = [s for s in summaries if s["complete"]]
    if not ok:
        return None
    return max(ok, key=lambda s: (s[key], s[other], -s["index"]))


def run_tune(
    c: TuneConfig, n_jobs: int = 1, scheduler: str | None = None, command: str | None = None
) -> dict[str, Any]:
    """Train every (point, seed) run (joblib ``n_jobs`` or Dask ``scheduler``, resuming each from its
    checkpoint), score them on the validation seeds and write ``tune.csv``, ``tune.json`` and
    ``tune.png`` into ``c.out``; returns the record of ``tune.json``.  Call :func:`check_tune` first."""
    from gfb_env.sweeps import run_sweep

    t0 = time.perf_counter()
    c.out.mkdir(parents=True, exist_ok=True)
    for p in c.points:
        c.point_dir(p).mkdir(exist_ok=True)
        c.point_yaml(p).write_text(_yaml_text(c, p))  # check_tune: the same entry, or a new point
    jobs = []
    for p in c.points:
        for r in c.seeds:
            d = {**c.run_config(p, r).as_dict(), "command": command, "progress_bar": False}
            jobs.append(d)
    recs = run_sweep(train_mod._train_point, jobs, n_jobs=n_jobs, scheduler=scheduler, desc="grid runs")
    # a failed run, or one a Ctrl-C interrupted (its run.json says so), is not scored
    errors = {
        rec["point"]["out"]: rec["error"] or "interrupted"
        for rec in recs
        if rec["error"] is not None or rec["result"].get("interrupted")
    }
    rows, summaries = [], []
    for p in c.points:
        scores = []
        for r in c.seeds:
            run_dir = c.point_dir(p) / f"seed{r}"
            row = {"point": p.index, "name": p.name, **p.settings, "seed": r}
            err = errors.get(str(run_dir))
            if err is None:
                s = score_run(run_dir)
                scores.append(s)
                row.update(s)
            row["run_dir"] = str(run_dir)
            row["error"] = err or ""
            rows.append(row)
        summaries.append(
            {
                "index": p.index,
                "name": p.name,
                "settings": p.settings,
                "hyperparams": str(c.point_yaml(p)),
                "seeds_scored": len(scores),
                "complete": len(scores) == len(c.seeds),
                "mean_best_return": _mean([s["best_mean_return"] for s in scores]),
                "mean_final_return": _mean([s["final_mean_return"] for s in scores]),
                "mean_best_success_rate": _mean([s["best_success_rate"] for s in scores]),
                "mean_final_success_rate": _mean([s["final_success_rate"] for s in scores]),
                "env_steps": sum(s["timesteps"] for s in scores),
                "wall_time_s": round(sum(s["wall_time_s"] for s in scores), 1),
            }
        )
    chosen = choose_point(summaries, c.rule)
    _write_csv(c.out / "tune.csv", rows, list(c.grid))
    steps = sum(s["env_steps"] for s in summaries)
    run_wall = sum(s["wall_time_s"] for s in summaries)
    record = {
        "algo": c.base.algo,
        "env_id": c.base.env_id,
        "frame_stack": c.base.frame_stack,
        "base_hyperparams": str(c.base.hyperparams or f"agents/hyperparams/{c.base.algo}.yml"),
        "grid": c.grid,
        "points": len(c.points),
        "seeds": list(c.seeds),
        "timesteps_per_run": c.base.timesteps,
        "eval_freq": c.base.eval_freq,
        "validation_seeds": VALIDATION.first(c.base.eval_episodes),
        "test_seeds_used": False,
        "budget": {
            "runs": len(c.points) * len(c.seeds),
            "env_steps": steps,
            # the runs' own wall times (all their sessions), summed: the compute of the search; the
            # elapsed time of this invocation is shorter with --n-jobs > 1 and when runs were resumed
            "run_wall_time_s": round(run_wall, 1),
            "this_invocation_wall_time_s": round(time.perf_counter() - t0, 1),
        },
        "rule": {
            "name": c.rule,
            "maximises": RULES[c.rule],
            "text": (
                f"the point with the largest mean over its {len(c.seeds)} training seed(s) of the "
                f"{'best' if c.rule == 'best' else 'last'} validation mean return (first "
                f"{c.base.eval_episodes} VALIDATION seeds); ties to the other score, then the earlier "
                f"point; only points with every seed scored"
            ),
        },
        "chosen": chosen,
        "per_point": summaries,
        "failed_runs": sorted(errors),
        "command": command,
    }
    train_mod._atomic_write_json(c.out / "tune.json", record)
    plot_tune(c.out / "tune.png", rows, summaries, chosen, title=f"{c.base.algo} on {c.base.env_id}")
    return record


_CSV_SCORES = (
    "timesteps",
    "best_mean_return",
    "best_timesteps",
    "best_success_rate",
    "final_mean_return",
    "final_timesteps",
    "final_success_rate",
    "validation_episodes",
    "validation_seeds",
    "wall_time_s",
    "env_steps_per_s",
)


def _write_csv(path: Path, rows: list[dict], grid_names: list[str]) -> None:
    cols = ["point", "name", *grid_names, "seed", *_CSV_SCORES, "run_dir", "error"]
    tmp = path.with_name(path.name + ".tmp")
    with tmp.open("w", newline="") as fh:
        w = csv.DictWriter(fh, fieldnames=cols, extrasaction="ignore")
        w.writeheader()
        for row in rows:
            w.writerow({k: row.get(k, "") for k in cols})
    tmp.replace(path)


def plot_tune(path: Path, rows: list[dict], summaries: list[dict], chosen: dict | None, title: str) -> Path:
    """Validation mean return per grid point: every seed's best (filled) and last (open) validation,
    the means over seeds as bars' tops, the chosen point marked."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    n = len(summaries)
    fig, ax = plt.subplots(figsize=(max(5.0, 1.2 * n + 2), 4.2))
    seeds = sorted({r["seed"] for r in rows})
    for k, seed in enumerate(seeds):
        dx = (k - (len(seeds) - 1) / 2) * 0.12
        mine = [r for r in rows if r["seed"] == seed and "best_mean_return" in r]
        xs = [r["point"] + dx for r in mine]
        ax.plot(
            xs, [r["best_mean_return"] for r in mine], "o", color=f"C{k % 10}", label=f"seed {seed}: best"
        )
        ax.plot(xs, [r["final_mean_return"] for r in mine], "o", mfc="none", color=f"C{k % 10}",
                label=f"seed {seed}: last")  # fmt: skip
    for s in summaries:
        if s["mean_best_return"] is not None:
            ax.hlines(s["mean_best_return"], s["index"] - 0.3, s["index"] + 0.3, color="k", lw=1.5)
            ax.hlines(s["mean_final_return"], s["index"] - 0.3, s["index"] + 0.3, color="k", lw=1, ls="--")
    if chosen is not None:
        ax.axvspan(chosen["index"] - 0.4, chosen["index"] + 0.4, color="C2", alpha=0.15, label="chosen")
    ax.set_xticks(range(n))
    ax.set_xticklabels([s["name"].replace(",", "\n") for s in summaries], fontsize=7)
    ax.set_ylabel("validation mean return")
    ax.set_title(f"{title}\nlines: mean over seeds (solid: best, dashed: last validation)", fontsize=9)
    ax.grid(alpha=0.3)
    ax.legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return Path(path)

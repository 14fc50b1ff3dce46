"""The package as users install it: build the wheel, install it into a fresh virtual environment and,
from a folder outside the repository, make and step every task, load every committed policy and run
``gfb params``.

The fresh environment reuses the dependencies of the running interpreter: a ``.pth`` file lists the
running interpreter's site-packages folders as plain paths, so their modules are importable but their own
``.pth`` files (the editable install of this checkout) are not executed; the wheel is installed into the
fresh environment itself, which comes first on ``sys.path``.
"""

from __future__ import annotations

import json
import os
import shutil
import site
import subprocess
import sys
import textwrap
import time
import tomllib
import venv
import zipfile
from pathlib import Path

REPO = Path(__file__).resolve().parents[2]

#: files the code reads at run time, which must be in the wheel
DATA_FILES = (
    "gfb_env/envs/data/task_constants.json",
    "gfb_env/data/stability_map.csv",
    "gfb_env/data/hysteresis_map.csv",
    # the bearing files `gfb --bearing NAME` reads
    "gfb_env/data/bearings/table1.toml",
    "gfb_env/data/bearings/table1_frictional.toml",
    "gfb_env/data/bearings/small_turbocompressor.toml",
    "gfb_env/data/hysteresis_map_tasks.csv",
    "gfb_agents/hyperparams/ppo.yml",
    "gfb_agents/hyperparams/sac.yml",
    "gfb_agents/hyperparams/recurrentppo.yml",
    "gfb_agents/hyperparams/asymmetric_ppo.yml",
    "gfb_agents/hyperparams/privileged_ppo.yml",
    "gfb_agents/hyperparams/teacher_student.yml",
    # the v1 learned agents: one folder per training seed
    *(
        f"gfb_agents/policies/{task}-v1_ppo_fs4/seed{r}/{f}"
        for task in ("RunUp", "RunUpRandomized", "WhirlRecovery")
        for r in range(5)
        for f in ("model.zip", "vecnormalize.pkl", "policy.json")
    ),
    # and every other committed policy file the evaluator reads (SAC, RecurrentPPO, ...)
    *sorted(
        "gfb_agents/" + str(f.relative_to(REPO / "agents"))
        for f in (REPO / "agents" / "policies").rglob("*")
        if f.suffix in (".zip", ".pkl", ".json", ".pt")
    ),
)

CHECKS = textwrap.dedent(
    """
    import json, math, sys, warnings
    import numpy as np
    import gymnasium as gym
    import gfb_env, gfb_agents, gfb_experiments
    from gfb_env.envs import ENV_IDS, make_env
    from gfb_env.envs._data import TaskConstantsWarning
    from gfb_env.analysis import optimal_foil_damping
    from gfb_agents.learned.evaluate import load_learned_policies
    from gfb_agents.nominal_map import NominalMap
    from gfb_agents.learned.train import load_hyperparams

    warnings.simplefilter("error", TaskConstantsWarning)  # a recompute would mean missing data
    out = {"files": {m.__name__: m.__file__ for m in (gfb_env, gfb_agents, gfb_experiments)},
           "tasks": {}, "policies": {}}
    for env_id in ENV_IDS:
        env = gym.make(env_id)
        obs, _ = env.reset(seed=0)
        ok = bool(np.isfinite(obs).all())
        for _ in range(3):
            obs, r, term, trunc, info = env.step(env.action_space.sample())
            ok &= bool(np.isfinite(obs).all() and math.isfinite(r))
            if term or trunc:
                break
        out["tasks"][env_id] = ok
        env.close()
    for pol in load_learned_policies():
        env = make_env(pol.env_id)  # the committed v1 policies: on the retired envs, for the record
        obs, _ = env.reset(seed=0)
        action, _ = pol.predict(obs)
        out["policies"][pol.name] = bool(env.action_space.contains(np.asarray(action, dtype=np.float32)))
        env.close()
    out["hyperparams"] = sorted(load_hyperparams("sac", "gfb_env/WhirlRecovery-v2"))
    out["d_opt_kw1"] = optimal_foil_damping(1.0)
    NominalMap.from_env(gym.make("gfb_env/RunUp-v2"))  # reads the shipped hysteresis map
    print(json.dumps(out))
    """
)


def _fresh_env() -> dict[str, str]:
    """No PYTHONPATH (the checkout must not leak in) and single-threaded BLAS."""
    env = {k: v for k, v in os.environ.items() if k != "PYTHONPATH" and not k.startswith("VIRTUAL_ENV")}
    env.update(OMP_NUM_THREADS="1", OPENBLAS_NUM_THREADS="1", MKL_NUM_THREADS="1")
    return env


def _run(cmd: list[str], cwd: Path, timeout: float) -> subprocess.CompletedProcess:
    res = subprocess.run(cmd, cwd=cwd, env=_fresh_env(), capture_output=True, text=True, timeout=timeout)
    assert res.returncode == 0, f"{cmd} failed:\n{res.stdout[-2000:]}\n{res.stderr[-4000:]}"
    return res


def test_wheel_installs_and_runs_outside_the_repository(tmp_path):
    t0 = time.perf_counter()
    # 1. build the wheel from a copy of the checkout (a build in place would write build/ and *.egg-info)
    src = _mkdir(tmp_path / "src")
    ignore = shutil.ignore_patterns("__pycache__", "*.pyc", "*.nbi", "*.nbc")
    for f in [REPO / "pyproject.toml", REPO / "README.md", *REPO.glob("LICENSE*")]:
        shutil.copy2(f, src / f.name)
    for pkg in ("gfb_env", "agents", "experiments"):
        shutil.copytree(REPO / pkg, src / pkg, ignore=ignore)
    dist = tmp_path / "dist"
    build = [sys.executable, "-m", "pip", "wheel", "--no-deps", "--no-build-isolation", "-q", "-w", str(dist)]
    _run([*build, "."], src, 240)
    (wheel,) = dist.glob("gfb_env-*.whl")
    names = set(zipfile.ZipFile(wheel).namelist())
    missing = [f for f in DATA_FILES if f not in names]
    assert not missing, f"wheel lacks {missing}"
    tops = {n.split("/")[0] for n in names if not n.split("/")[0].endswith(".dist-info")}
    assert tops == {"gfb_env", "gfb_agents", "gfb_experiments"}, tops  # no bare agents/experiments

    # 2. a fresh virtual environment that sees the running interpreter's dependencies as plain paths
    venv_dir = tmp_path / "venv"
    venv.EnvBuilder(with_pip=False, symlinks=True).create(venv_dir)
    py = venv_dir / "bin" / "python"
    purelib = Path(
        _run(
            [str(py), "-c", "import sysconfig; print(sysconfig.get_paths()['purelib'])"], tmp_path, 60
        ).stdout.strip()
    )
    deps = [p for p in dict.fromkeys(site.getsitepackages() + sys.path) if p.endswith("site-packages")]
    (purelib / "_parent_deps.pth").write_text("\n".join(deps) + "\n")
    _run(
        [str(py), "-m", "pip", "install", "-q", "--no-deps", "--no-index", "--force-reinstall", str(wheel)],
        tmp_path,
        120,
    )

    # 3. from a folder outside the repository
    work = _mkdir(tmp_path / "elsewhere")
    res = _run([str(py), "-c", CHECKS], work, 300)
    out = json.loads(res.stdout.strip().splitlines()[-1])
    for mod, f in out["files"].items():
        assert Path(f).resolve().is_relative_to(purelib.resolve()), f"{mod} imported from {f}"
    from gfb_env.envs import ENV_IDS

    assert out["tasks"] == dict.fromkeys(ENV_IDS, True)
    # every committed model (one per training seed of each learned agent) loads and acts from the wheel
    # (a model.zip, or a deployed actor alone: actor.pt, the v2 students)
    committed = {
        f"{z.parent.parent.name}/{z.parent.name}"
        for pat in ("*/seed*/model.zip", "*/seed*/actor.pt")
        for z in (REPO / "agents" / "policies").glob(pat)
    }
    assert len(committed) >= 9 and out["policies"] == dict.fromkeys(committed, True)
    assert "policy" in out["hyperparams"] and 1.0 < out["d_opt_kw1"] < 10.0
    gfb = venv_dir / "bin" / "gfb"
    assert gfb.read_text().startswith(f"#!{py}"), gfb.read_text()[:200]
    params = json.loads(_run([str(gfb), "params", "--json"], work, 60).stdout)
    assert params, "gfb params --json printed nothing"
    # issue 18, defect 1: the README's bearing files ship with the wheel and go by name
    small = json.loads(
        _run([str(gfb), "bearing", "--bearing", "small_turbocompressor", "--json"], work, 60).stdout
    )
    assert small["parameters"]["radius_m"] == 12.5e-3, small["parameters"]
    version = tomllib.loads((REPO / "pyproject.toml").read_text())["project"]["version"]
    assert _run([str(gfb), "--version"], work, 60).stdout.strip() == f"gfb {version}"
    print(f"wheel test: {time.perf_counter() - t0:.1f} s")


def _mkdir(p: Path) -> Path:
    p.mkdir(parents=True, exist_ok=True)
    return p

"""Copy trained policies from a training folder (``runs/...``, gitignored) into ``agents/policies/<name>/``.

    python -m gfb_experiments.export_policy RUN_DIR NAME [--which {best,final}]   # the command line

``RUN_DIR`` is one run (``runs/<env>_<algo>/seed<r>``, with ``run.json``) or an experiment of several
training seeds (``runs/<env>_<algo>``, with ``seed*/run.json``).  For each run it copies ``model.zip`` and
``vecnormalize.pkl`` -- the checkpoint selected on the validation seeds (``best/``, default) or the final
model -- the learning curve, and writes ``policy.json`` (algo, env id, seed, frame stack, command, wall
time, throughput, timesteps, best validation, which model) and a ``README.md`` stating the same.  For
the methods trained with the privileged vector (``asymmetric_ppo``) the copy is the deployed actor alone,
``actor.pt`` (:class:`gfb_agents.learned.asymmetric.DeployedActor`: no critic, no optimiser state) instead
of ``model.zip``.  Every copied ``model.zip`` is written without optimiser state
(:func:`strip_optimizer_state`: each ``*optimizer.pth`` keeps its parameter groups, its per-parameter
moments are dropped), so the committed policies stay small (issue 21) and SB3's own ``PPO.load`` /
``SAC.load`` still read them (as a fresh optimiser: fine-tuning starts its moments anew).
Several runs land in ``<name>/seed<r>/``, so the ladder
(:func:`gfb_agents.ladder.learned_entries`) reads them as one learned agent with one row per training
seed.  The evaluator
(:class:`gfb_agents.learned.evaluate.LearnedPolicy`) reads ``policy.json``.
"""

from __future__ import annotations

import io
import json
import shutil
import zipfile
from pathlib import Path

from gfb_agents.learned.evaluate import ACTOR_ONLY_ALGOS, POLICIES_DIR, TEACHER_ALGO, algo_class
from gfb_env import jsonio

__all__ = ["export_policy", "strip_optimizer_state", "has_optimizer_state"]

_KEYS = (
    "algo",
    "env_id",
    "env_kwargs",
    "seed",
    "n_envs",
    "frame_stack",
    "privileged",
    # a distilled student's teacher (a privileged_ppo run, or the oracle: teacher_kind, teacher_margin)
    "teacher",
    "teacher_kind",
    "teacher_margin",
    "teacher_timesteps",
    # the damping command's slew limit: part of the policy (LearnedPolicy applies it)
    "damping_slew",
    "damping_slew_reserve",
    "timesteps",
    "wall_time_s",
    "env_steps_per_s",
    "env_steps_per_s_excluding_validation",
    "command",
    "hyperparams",
    "best_validation",
    "validation_seeds",
    "sessions",
    "interrupted",
    # runs of the earlier layout
    "final_eval",
    "resumed_from",
    "previous_runs",
)


def _is_optimizer_entry(name: str) -> bool:
    # SB3 names them after the attribute: policy.optimizer, actor.optimizer, critic.optimizer,
    # ent_coef_optimizer
    return name.endswith("optimizer.pth")


def has_optimizer_state(zip_path: str | Path) -> bool:
    """Whether an SB3 ``model.zip`` holds an optimiser's per-parameter state (its moments)."""
    import torch as th

    with zipfile.ZipFile(zip_path) as zf:
        for name in zf.namelist():
            if _is_optimizer_entry(name):
                sd = th.load(io.BytesIO(zf.read(name)), map_location="cpu", weights_only=True)
                if sd.get("state"):
                    return True
    return False


def strip_optimizer_state(src: str | Path, dest: str | Path | None = None) -> Path:
    """Write the SB3 ``model.zip`` ``src`` to ``dest`` (default: in place) with every optimiser's
    per-parameter state (Adam's moments and step counts: about 2x the weights) removed; the parameter
    groups (learning rate, betas) stay, so SB3's ``load`` (its exact match of the saved objects) reads
    the file as a model with a fresh optimiser.  Everything else, the weights and ``data`` included, is
    copied byte for byte: the policy's actions do not change."""
    import torch as th

    src = Path(src)
    dest = src if dest is None else Path(dest)
    out = io.BytesIO()
    with zipfile.ZipFile(src) as zin, zipfile.ZipFile(out, "w", zipfile.ZIP_DEFLATED) as zout:
        for info in zin.infolist():
            blob = zin.read(info.filename)
            if _is_optimizer_entry(info.filename):
                sd = th.load(io.BytesIO(blob), map_location="cpu", weights_only=True)
                buf = io.BytesIO()
                th.save({"state": {}, "param_groups": sd["param_groups"]}, buf)
                blob = buf.getvalue()
            zout.writestr(info, blob)
    dest.write_bytes(out.getvalue())
    return dest


def _sources(run: Path, which: str) -> tuple[Path, Path]:
    from gfb_agents.learned.asymmetric import ACTOR_FILE

    if (run / ACTOR_FILE).exists():  # a distilled student: the actor alone already
        d = run / "best" if which == "best" and (run / "best" / ACTOR_FILE).exists() else run
        return d / ACTOR_FILE, d / "vecnormalize.pkl"
    if which == "final":
        return run / "model.zip", run / "vecnormalize.pkl"
    if (run / "best" / "model.zip").exists():
        return run / "best" / "model.zip", run / "best" / "vecnormalize.pkl"
    # a run of the earlier layout (EvalCallback's best model)
    return run / "eval" / "best_model.zip", run / "eval" / "best_vecnormalize.pkl"


def _export_run(run: Path, dest: Path, name: str, which: str) -> Path:
    meta = json.loads((run / "run.json").read_text())
    if meta.get("algo") == TEACHER_ALGO:
        raise ValueError(
            f"{run}: a {TEACHER_ALGO} teacher reads the privileged vector and is not exported; export its "
            "distilled student (--algo teacher_student)"
        )
    src_model, src_vn = _sources(run, which)
    if not src_model.exists():
        raise FileNotFoundError(f"no {src_model}")
    dest.mkdir(parents=True, exist_ok=True)
    from gfb_agents.learned.asymmetric import ACTOR_FILE, DeployedActor

    if src_model.name == ACTOR_FILE:
        shutil.copy2(src_model, dest / ACTOR_FILE)
    elif meta["algo"] in ACTOR_ONLY_ALGOS:
        # the actor alone: what the deployed policy runs (the critic read the privileged vector)
        policy = algo_class(meta["algo"]).load(str(src_model), device="cpu").policy
        DeployedActor.from_policy(policy).save(
            dest / ACTOR_FILE, {"algo": meta["algo"], "env_id": meta["env_id"], "model": which}
        )
    else:
        strip_optimizer_state(src_model, dest / "model.zip")
    if src_vn.exists():
        shutil.copy2(src_vn, dest / "vecnormalize.pkl")
    if (run / "learning_curve.png").exists():
        shutil.copy2(run / "learning_curve.png", dest / "learning_curve.png")
    info = {k: meta.get(k) for k in _KEYS if k in meta}
    info["model"] = which
    (dest / "policy.json").write_text(jsonio.dumps(info, indent=2))
    bv = meta.get("best_validation") or {}
    lines = [
        f"# {name}",
        "",
        f"{meta['algo'].upper()} policy for `{meta['env_id']}` ({which} model of the run), trained by",
        "",
        "```",
        meta["command"],
        "```",
        "",
        f"* training seed {meta['seed']}, {meta['n_envs']} env(s), {meta['timesteps']} environment steps, "
        f"wall time {meta['wall_time_s'] / 60:.1f} min"
        + (f" ({meta['env_steps_per_s']} env steps/s)" if "env_steps_per_s" in meta else "")
        + (" (stopped by Ctrl-C before the requested total)" if meta.get("interrupted") else ""),
        *(
            [
                f"* damping command slew-limited to {meta['damping_slew']:g} action units per control step "
                + (
                    f", saving up to {meta['damping_slew_reserve']:g} of unused allowance"
                    if meta.get("damping_slew_reserve") is not None
                    else ""
                )
                + " (`damping_slew`; part of the policy: `gfb_agents.learned.slew`)"
            ]
            if meta.get("damping_slew") is not None
            else []
        ),
        f"* model selection on the validation seeds: best mean return {bv.get('mean_return', '?')} at "
        f"{bv.get('timesteps', '?')} steps (see `policy.json`)",
        "* files: "
        + (
            "`actor.pt` (the actor alone)"
            if meta["algo"] in ACTOR_ONLY_ALGOS
            else "`model.zip` (SB3, without optimiser state)"
        )
        + ", `vecnormalize.pkl` (observation statistics; load with "
        "`gfb_agents.learned.evaluate.LearnedPolicy`), `learning_curve.png`, `policy.json`",
        "* benchmark results: `results/benchmark_agents.md`",
        "",
        "![learning curve](learning_curve.png)",
        "",
    ]
    (dest / "README.md").write_text("\n".join(lines))
    return dest


def export_policy(
    run_dir: str | Path, name: str, which: str = "best", root: str | Path = POLICIES_DIR
) -> Path:
    """Export the run (or every ``seed*/`` run) of ``run_dir`` to ``root / name``; returns that folder."""
    run = Path(run_dir)
    if which not in ("final", "best"):
        raise ValueError(f"which must be 'final' or 'best', got {which!r}")
    if (run / "run.json").exists():
        return _export_run(run, Path(root) / name, name, which)
    runs = sorted(d for d in run.glob("seed*") if (d / "run.json").exists()) if run.is_dir() else []
    if not runs:
        raise FileNotFoundError(
            f"{run} has no run.json nor seed*/run.json (not a gfb_agents.learned.train output)"
        )
    for d in runs:
        _export_run(d, Path(root) / name / d.name, name, which)
    return Path(root) / name

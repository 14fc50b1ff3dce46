"""Copy a trained policy from a run directory (``runs/...``, gitignored) into ``agents/policies/<name>/``.

    python -m gfb_agents.export_policy RUN_DIR NAME [--which {final,best}]

Copies ``model.zip`` and ``vecnormalize.pkl`` (final, or EvalCallback's best with its statistics), the
learning curve, and writes ``policy.json`` (algo, env id, seed, command, wall time, timesteps, final
evaluation, which model) and a ``README.md`` stating the same.  The evaluator
(:class:`gfb_agents.evaluate.LearnedPolicy`) reads ``policy.json``.
"""

from __future__ import annotations

import json
import shutil
from pathlib import Path

from gfb_agents.evaluate import POLICIES_DIR
from gfb_env import jsonio
from gfb_env._cli_common import OneLineParser

__all__ = ["export_policy"]


def export_policy(
    run_dir: str | Path, name: str, which: str = "final", root: str | Path = POLICIES_DIR
) -> Path:
    """Export ``run_dir``'s final (or best-evaluated) model to ``root / name``; returns the directory."""
    run = Path(run_dir)
    meta_p = run / "run.json"
    if not meta_p.exists():
        raise FileNotFoundError(f"{run} has no run.json (not a gfb_agents.train output directory)")
    if which not in ("final", "best"):
        raise ValueError(f"which must be 'final' or 'best', got {which!r}")
    meta = json.loads(meta_p.read_text())
    src_model = run / ("model.zip" if which == "final" else "eval/best_model.zip")
    src_vn = run / ("vecnormalize.pkl" if which == "final" else "eval/best_vecnormalize.pkl")
    if not src_model.exists():
        raise FileNotFoundError(f"no {src_model}")
    dest = Path(root) / name
    dest.mkdir(parents=True, exist_ok=True)
    shutil.copy2(src_model, dest / "model.zip")
    if src_vn.exists():
        shutil.copy2(src_vn, dest / "vecnormalize.pkl")
    if (run / "learning_curve.png").exists():
        shutil.copy2(run / "learning_curve.png", dest / "learning_curve.png")
    keys = (
        "algo",
        "env_id",
        "env_kwargs",
        "seed",
        "n_envs",
        "timesteps",
        "wall_time_s",
        "command",
        "hyperparams",
        "final_eval",
        "resumed_from",
        "previous_runs",
        "interrupted",
    )
    info = {k: meta.get(k) for k in keys if k in meta}
    info["model"] = which
    (dest / "policy.json").write_text(jsonio.dumps(info, indent=2))
    fe = meta.get("final_eval", {})
    lines = [
        f"# {name}",
        "",
        f"{meta['algo'].upper()} policy for `{meta['env_id']}` ({which} model of the run), trained by",
        "",
        "```",
        meta["command"],
        "```",
        "",
        f"* seed {meta['seed']}, {meta['n_envs']} env(s), {meta['timesteps']} environment steps, "
        f"wall time {meta['wall_time_s'] / 60:.1f} min on the shared 2-core CPU machine"
        + (" (plus the runs it resumed, see `policy.json`)" if meta.get("resumed_from") else "")
        + (" (stopped by Ctrl-C before the requested total)" if meta.get("interrupted") else ""),
        f"* evaluation during training (deterministic, {fe.get('eval_episodes', '?')} episodes per point): "
        f"last mean return {fe.get('last_mean_return', float('nan')):.1f}, best "
        f"{fe.get('best_mean_return', float('nan')):.1f} at {fe.get('best_timesteps', '?')} steps",
        "* files: `model.zip` (SB3), `vecnormalize.pkl` (observation statistics; load with "
        "`gfb_agents.evaluate.LearnedPolicy`), `learning_curve.png`, `policy.json`",
        "* benchmark results: `results/benchmark_agents.md`",
        "",
        "![learning curve](learning_curve.png)",
        "",
    ]
    (dest / "README.md").write_text("\n".join(lines))
    return dest


def main(argv: list[str] | None = None) -> int:
    ap = OneLineParser(prog="python -m gfb_agents.export_policy", description=__doc__.splitlines()[0])
    ap.add_argument("run_dir")
    ap.add_argument("name", help="directory name under agents/policies, e.g. WhirlRecovery_sac")
    ap.add_argument("--which", choices=("final", "best"), default="final")
    a = ap.parse_args(argv)
    try:
        print(export_policy(a.run_dir, a.name, a.which))
    except (FileNotFoundError, ValueError) as exc:
        ap.error(str(exc))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())

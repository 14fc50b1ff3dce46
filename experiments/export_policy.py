"""Copy trained policies into ``agents/policies/<name>/``: the command line of
:func:`gfb_agents.learned.export_policy.export_policy` (what is copied and why: its module docstring).

    python -m gfb_experiments.export_policy RUN_DIR NAME [--which {best,final}]
"""

from __future__ import annotations

from gfb_agents.learned.export_policy import export_policy
from gfb_env.scripting import OneLineParser

__all__ = ["main"]


def main(argv: list[str] | None = None) -> int:
    ap = OneLineParser(prog="python -m gfb_experiments.export_policy", description=__doc__.splitlines()[0])
    ap.add_argument("run_dir")
    ap.add_argument("name", help="directory name under agents/policies, e.g. RunUpRandomized-v2_sac")
    ap.add_argument("--which", choices=("final", "best"), default="best")
    a = ap.parse_args(argv)
    try:
        print(export_policy(a.run_dir, a.name, a.which))
    except (FileNotFoundError, ValueError) as exc:
        ap.error(str(exc))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())

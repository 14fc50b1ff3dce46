"""``margin_aim_1x``: ``margin_search_1x``'s estimates and damping, with the speed set-point aimed at its own
posterior-mean boundary less a fixed margin (issue 19 s.3: the strongest honest rule; written by the outside
audit of the v2 headroom claims, ``results/audit_v2_rules/``, and adopted into the ladder unchanged).

Why: ``margin_search_1x``'s posterior-mean stability boundary at the damping it chooses, converted to rpm on
its refitted bearing, lies within -1.5 % / +0.4 % of the actual plant's best stable speed (mean -0.6 %,
sd 0.8 %; DEV seeds 5000-5006, the privileged truth used only to score the estimates:
``results/audit_v2_rules/diagnose.py``), yet its decision holds 1-6.5 % below that estimate: it is told the
refitted boundary is uncertain by 2 % (``rel_sd_refined``, measured on v1's 8 seeds) and asks a decay-rate
margin of 0.002 per tau chosen on v1.  With the v2 tasks' success window 2 % wide, that care costs most of
the window.  This rule keeps every estimate of ``margin_search_1x`` (the bearing fit and its bias-free
refit, the unbalance and 1x probes, the shock decays, the whirl guard and its cap, the damping chosen by
:func:`~gfb_agents.rules.operating_point.choose_operating_point`) and, once the bearing is refitted, sets

    Lambda_set = min(Lambda_command, cap, (1 - margin) E_post[Lambda_c(g D_cmd)])

with ``margin`` = 1 % (the oracle's own margin applied to the rule's estimate; fixed from the DEV evidence
before any hidden episode ran) or 0.5 % (``margin_aim_1x_05``; the DEV diagnosis put 7 of 7 DEV set-points
inside the window at 0.5 %, 5 of 7 at 1 %).  Before the refit, and after a whirl has lowered the cap,
``margin_search``'s decision stands.

On the audit's hidden seeds (8 000 000-8 000 099) it raised RunUpRandomized-v2's best rule from 0.60 to
0.74 normalised IQM and RunUp-v2's from 0.73 to 0.88-0.89 (``results/audit_v2_rules/FINDINGS.md``).

Only public information, exactly as ``margin_search_1x`` (the observation; nothing of the episode).
"""

from __future__ import annotations

import math

import numpy as np

from gfb_agents.rules.margin_search import MarginSearchMemory
from gfb_agents.rules.margin_search_1x import MarginSearch1xAgent

__all__ = ["MarginAim1xAgent"]


class MarginAim1xAgent(MarginSearch1xAgent):
    """``margin_aim_1x`` (module docstring).

    Args:
        margin: relative margin below the posterior-mean boundary of the chosen damping, in [0, 0.5).
        kw: :class:`MarginSearch1xAgent`'s.
    """

    #: the default margin (the oracle's own, 1 %)
    MARGIN = 0.01

    def __init__(self, env, margin: float | None = None, name: str = "margin_aim_1x", **kw):
        margin = self.MARGIN if margin is None else float(margin)
        if not 0.0 <= margin < 0.5:  # before the parent's tables are built: bad input fails first
            raise ValueError(f"margin must lie in [0, 0.5), got {margin!r}")
        super().__init__(env, name=name, **kw)
        self.margin = margin
        #: the last refined decision's posterior-mean boundary (bearing number) at the chosen damping
        self.last_boundary: float | None = None

    def boundary_estimate(self, m: MarginSearchMemory) -> float:
        """E_post[Lambda_c(g D_cmd)]: the posterior-mean critical bearing number at the commanded damping."""
        post = m.post
        return float(post.weights @ m.table.critical(post.gains * m.d_cmd, 0.0))

    def _decide(self, m: MarginSearchMemory, obs: np.ndarray) -> None:
        super()._decide(m, obs)  # margin_search's decision: the damping, the cap, the set-point before refit
        if not m.refined or m.table is None:
            return
        b = m.bearing
        lc = self.boundary_estimate(m)
        self.last_boundary = lc
        cmd = self.command_rpm(obs, m)
        lam_cmd = b.bearing_number_at(cmd) if cmd is not None else math.inf
        cap = min(m.cap, 0.98 * b.bearing_number_at(self.max_speed_rpm))
        m.setpoint = b.speed_rpm_at(min(lam_cmd, cap, (1.0 - self.margin) * lc))

"""The audit's rule for RunUpRandomized-v2 / RunUp-v2: ``margin_search_1x``'s estimation (bearing fit and
bias-free refit, 1x probe, shock decays, whirl guard), with the decision's uncertainty *calibrated on DEV
seeds* instead of v1's settings.

Why (DEV seeds 5000-5015, analysis of ``margin_search_1x``'s own estimates against the privileged truth,
``diagnose.py``): its posterior-mean boundary at the damping it chooses lies within ~1-1.5 % of the actual
plant's best stable speed, yet it holds 4-8 % below that estimate: the decision is told the refitted
bearing's boundary is uncertain by 2 % (``rel_sd_refined``, measured on v1's 8 seeds) and asks a decay-rate
margin of 0.002 per tau (``safe_growth_rate``, chosen on v1, where a shock's ring-down inside the final
window failed the certificate; v2's certificate forgives a decaying ring-down).  With the success window
2 % wide, a 2 % sd leaves most episodes below it.

Only public information, exactly as ``margin_search_1x`` (the observation; nothing of the episode).  The
parameters differ, nothing else.
"""

from __future__ import annotations

import math

from gfb_agents.rules.margin_search_1x import MarginSearch1xAgent

__all__ = ["AuditAim1x", "AuditAim1x05", "AuditMargin1x", "AuditMargin1xB", "AuditMargin1xC"]


class AuditMargin1x(MarginSearch1xAgent):
    """``margin_search_1x`` with a calibrated decision (module docstring).

    Args:
        rel_sd_refined: relative sd of the refitted plant's boundary the decision assumes.
        safe_growth_rate: the decision's decay-rate margin (``level``; 0: the boundary itself).
        kw: :class:`MarginSearch1xAgent`'s.
    """

    REL_SD_REFINED = 0.01
    SAFE_GROWTH_RATE = -0.001

    def __init__(self, env, rel_sd_refined: float | None = None, safe_growth_rate: float | None = None, **kw):
        sgr = self.SAFE_GROWTH_RATE if safe_growth_rate is None else float(safe_growth_rate)
        kw.setdefault("name", "audit_margin_1x")
        super().__init__(env, safe_growth_rate=sgr, **kw)
        self.rel_sd_refined = self.REL_SD_REFINED if rel_sd_refined is None else float(rel_sd_refined)
        if not self.rel_sd_refined > 0:
            raise ValueError(f"rel_sd_refined must be > 0, got {rel_sd_refined!r}")


class AuditMargin1xB(AuditMargin1x):
    """Variant B (DEV tuning): the boundary itself as the stability level."""

    REL_SD_REFINED = 0.01
    SAFE_GROWTH_RATE = 0.0


class AuditMargin1xC(AuditMargin1x):
    """Variant C (DEV tuning): 1.25 % boundary sd, margin 0.001."""

    REL_SD_REFINED = 0.0125
    SAFE_GROWTH_RATE = -0.001


class AuditAim1x(MarginSearch1xAgent):
    """``audit_aim_1x``: ``margin_search_1x``'s estimates and damping choice, but the set-point aims at the
    posterior-mean boundary of the chosen damping less a fixed ``margin`` (the oracle's own rule, 1 %,
    applied to the rule's estimate) once the bearing is refitted along the run-up; before the refit, and
    after a whirl (the cap), ``margin_search``'s decision stands.

    Why: on DEV seeds 5000-5006 ``margin_search_1x``'s posterior-mean boundary at its damping was within
    -1.5 / +0.4 % of the actual best stable speed (mean -0.6 %, sd 0.8 %), while its decision held 1-6.5 %
    below that estimate (``diagnose.py``).
    """

    MARGIN = 0.01

    def __init__(self, env, margin: float | None = None, **kw):
        kw.setdefault("name", "audit_aim_1x")
        super().__init__(env, **kw)
        self.margin = self.MARGIN if margin is None else float(margin)
        if not 0.0 <= self.margin < 0.5:
            raise ValueError(f"margin must lie in [0, 0.5), got {margin!r}")

    def _decide(self, m, obs) -> None:
        super()._decide(m, obs)
        if not m.refined or m.table is None:
            return
        post, b = m.post, m.bearing
        lc = float(post.weights @ m.table.critical(post.gains * m.d_cmd, 0.0))
        cmd = self.command_rpm(obs, m)
        lam_cmd = b.bearing_number_at(cmd) if cmd is not None else math.inf
        cap = min(m.cap, 0.98 * b.bearing_number_at(self.max_speed_rpm))
        lam = min(lam_cmd, cap, (1.0 - self.margin) * lc)
        m.setpoint = b.speed_rpm_at(lam)


class AuditAim1x05(AuditAim1x):
    """``audit_aim_1x`` with a 0.5 % margin (DEV tuning)."""

    MARGIN = 0.005

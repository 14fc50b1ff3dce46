"""Statistics of the agent benchmark: per-episode normalisation and rliable's interval estimates.

* :func:`normalized_scores`: every episode's return on the task's scale, ``s = (R - mean R_naive) /
  (mean R_oracle - mean R_naive)``, the means over the task's evaluation seeds (all agents play the same
  seeds): 0 = the naive agent's mean, 1 = the oracle's -- as Atari's human-normalised score uses one random
  and one human reference per game.  An agent's mean score is its normalised mean return; the IQM is a
  robust location of its return distribution on that scale.  Not paired per seed: a per-seed difference
  ``R - R_naive`` is dominated by the naive's touchdowns (-100 on a quarter of the seeds), whose trimmed
  mean then says little (the oracle's own IQM of paired differences was 0.37 on RunUp-v1), and a per-seed
  denominator ``R_oracle - R_naive`` explodes where both tie (a first version; its IQM ranked a rule with
  a lower mean return first).  If the oracle's mean does not beat the naive's the task has no scale: every
  score is NaN and ``no_headroom`` is set.  ``oracle_lost_seeds`` counts the seeds on which the oracle
  scored below the naive (shocks, for instance).
* :func:`interval_estimates`: IQM (and mean) of a score matrix with stratified-bootstrap 95 % CIs from
  rliable (``rly.get_interval_estimates``).  The matrix is ``runs x episodes`` (one row per independent
  training seed; rules, naive and oracle have one row).  It goes to rliable transposed, as its
  ``(num_runs, num_tasks)`` = ``(episodes, runs)``: episodes are resampled *within* each training seed
  (the strata), and with two or more training seeds also the seeds themselves (rliable's
  ``task_bootstrap=True``), so the interval of a learned agent includes the seed-to-seed spread.
* :func:`paired_headroom`: the headroom of the oracle over a rule (IQM(oracle) - IQM(rule) and the same for
  the means, both on the normalised scale) with a *paired* bootstrap 95 % CI: the evaluation seeds are
  resampled and both agents' scores of a drawn seed go together, so the seed-to-seed variation they share
  (a hard draw is hard for both) cancels.  An agent with several training seeds is first averaged over
  them per evaluation seed (the CI is then over evaluation seeds only, not over training seeds).
* :func:`performance_profile_png`: rliable's score-distribution performance profile of every agent of a
  task (fraction of episodes with normalised score > tau), with bootstrap bands.

The bootstrap is seeded (:data:`gfb_agents.seeds.BOOTSTRAP_SEED`): the same scores give the same CIs.
rliable draws its indices from NumPy's global generator; it is seeded for the call and restored after.
"""

from __future__ import annotations

import contextlib
import math
from pathlib import Path

import numpy as np

from gfb_agents.seeds import BOOTSTRAP_SEED

__all__ = [
    "DEFAULT_REPS",
    "normalized_scores",
    "iqm",
    "interval_estimates",
    "paired_headroom",
    "performance_profile_png",
]

#: a mean oracle-naive margin below this fraction of the returns' size counts as none (rounding)
NO_HEADROOM_REL = 1e-9
#: bootstrap replications (rliable's default is 50 000; measured here: 2 s per call for 1 x 100 scores,
#: 4.5 s for 5 x 100, so a table of ~50 rows (two calls each) takes a few minutes)
DEFAULT_REPS = 10_000


#: the references a score can be normalised by: the naive's and oracle's means (the table's default) or IQMs
REFERENCES = ("mean", "iqm")


def normalized_scores(
    returns: np.ndarray, naive: np.ndarray, oracle: np.ndarray, reference: str = "mean"
) -> tuple[np.ndarray, dict]:
    """Per-episode normalised scores of ``returns`` (shape ``(runs, episodes)`` or ``(episodes,)``) on the
    scale of the naive and oracle returns of the same seeds (shape ``(episodes,)`` each).  ``reference``:
    ``"mean"`` (0 = the naive's mean, 1 = the oracle's) or ``"iqm"`` (their IQMs: then the naive's and
    oracle's normalised IQMs are exactly 0 and 1, consistent with an IQM table).

    Returns ``(scores, info)`` with ``scores`` of the shape of ``returns`` and ``info`` =
    ``{"mean_gap", "median_gap", "oracle_lost_seeds", "no_headroom", "reference", "reference_gap"}``
    (module docstring; ``reference_gap`` = the oracle's reference minus the naive's, the scale)."""
    if reference not in REFERENCES:
        raise ValueError(f"reference must be one of {', '.join(REFERENCES)}, got {reference!r}")
    r = np.asarray(returns, dtype=np.float64)
    n = np.asarray(naive, dtype=np.float64)
    o = np.asarray(oracle, dtype=np.float64)
    if n.ndim != 1 or n.shape != o.shape:
        raise ValueError(f"naive and oracle returns must be 1-D of one length, got {n.shape} and {o.shape}")
    if r.shape[-1] != n.shape[0]:
        raise ValueError(f"returns have {r.shape[-1]} episodes, naive/oracle {n.shape[0]}")
    gap = o - n
    mean_gap = float(np.mean(o) - np.mean(n)) if gap.size else math.nan
    info = {
        "mean_gap": mean_gap,
        "median_gap": float(np.median(gap)) if gap.size else math.nan,
        "oracle_lost_seeds": int(np.sum(gap < 0)),
        "no_headroom": False,
        "reference": reference,
    }
    if reference == "mean" or not gap.size:
        zero, ref_gap = (float(np.mean(n)) if gap.size else math.nan), mean_gap
    else:
        zero = iqm(n)
        ref_gap = iqm(o) - zero
    info["reference_gap"] = ref_gap
    # a margin at the level of rounding (relative to the returns' size) is no scale either
    scale = max(1.0, float(np.mean(np.abs(n))), float(np.mean(np.abs(o)))) if gap.size else 1.0
    if not (math.isfinite(ref_gap) and ref_gap > NO_HEADROOM_REL * scale):
        return np.full(r.shape, math.nan), info | {"no_headroom": True}
    return (r - zero) / ref_gap, info


def iqm(scores: np.ndarray) -> float:
    """Interquartile mean of all entries (rliable's ``metrics.aggregate_iqm``: 25 % trimmed mean)."""
    from rliable import metrics

    return float(metrics.aggregate_iqm(np.asarray(scores, dtype=np.float64)))


@contextlib.contextmanager
def _seeded_global_rng(seed: int):
    # rliable 1.2 draws from the legacy global generator (np.random.choice), so that is what to seed
    state = np.random.get_state()  # noqa: NPY002
    np.random.seed(seed)  # noqa: NPY002
    try:
        yield
    finally:
        np.random.set_state(state)  # noqa: NPY002


def interval_estimates(
    scores: np.ndarray,
    reps: int = DEFAULT_REPS,
    confidence: float = 0.95,
    seed: int = BOOTSTRAP_SEED,
) -> dict[str, float]:
    """IQM and mean of ``scores`` (``(runs, episodes)``, or ``(episodes,)`` for one run) with rliable's
    stratified-bootstrap percentile CIs (module docstring: strata = runs; runs resampled too when >= 2).

    Returns ``{"iqm", "iqm_low", "iqm_high", "mean", "mean_low", "mean_high"}``; all NaN if any score
    is not finite (a task without headroom)."""
    from rliable import library as rly
    from rliable import metrics

    s = np.asarray(scores, dtype=np.float64)
    if s.ndim == 1:
        s = s[None, :]
    if s.ndim != 2 or s.size == 0:
        raise ValueError(f"scores must be a non-empty (runs, episodes) matrix, got shape {s.shape}")
    if isinstance(reps, bool) or not isinstance(reps, int) or reps < 100:
        raise ValueError(f"reps must be an integer >= 100, got {reps!r}")
    keys = ("iqm", "iqm_low", "iqm_high", "mean", "mean_low", "mean_high")
    if not np.isfinite(s).all():
        return dict.fromkeys(keys, math.nan)
    mat = s.T  # rliable's (num_runs, num_tasks): here (episodes, training runs)

    def agg(x: np.ndarray) -> np.ndarray:
        return np.array([metrics.aggregate_iqm(x), metrics.aggregate_mean(x)])

    if mat.shape[0] == 1:  # one episode: no spread to resample
        p = agg(mat)
        return dict(zip(keys, (p[0], p[0], p[0], p[1], p[1], p[1]), strict=True))
    with _seeded_global_rng(seed):
        point, ci = rly.get_interval_estimates(
            {"a": mat},
            agg,
            reps=reps,
            confidence_interval_size=confidence,
            task_bootstrap=mat.shape[1] >= 2,
        )
    p, c = point["a"], ci["a"]
    return {
        "iqm": float(p[0]),
        "iqm_low": float(c[0, 0]),
        "iqm_high": float(c[1, 0]),
        "mean": float(p[1]),
        "mean_low": float(c[0, 1]),
        "mean_high": float(c[1, 1]),
    }


def _per_seed(x, name: str) -> np.ndarray:
    """``x`` as one score per evaluation seed: a ``(runs, episodes)`` matrix is averaged over its runs."""
    a = np.asarray(x, dtype=np.float64)
    if a.ndim == 2:
        a = a.mean(axis=0)  # several training seeds: their mean per evaluation seed
    if a.ndim != 1 or a.size == 0:
        raise ValueError(
            f"{name} must be a non-empty (episodes,) or (runs, episodes) array, got shape {a.shape}"
        )
    if not np.isfinite(a).all():
        raise ValueError(f"{name} has non-finite scores ({int(np.sum(~np.isfinite(a)))} of {a.size})")
    return a


def paired_headroom(
    oracle: np.ndarray,
    rule: np.ndarray,
    reps: int = DEFAULT_REPS,
    confidence: float = 0.95,
    seed: int = BOOTSTRAP_SEED,
    paired: bool = True,
) -> dict[str, float]:
    """Headroom of ``oracle`` over ``rule``: normalised scores on the same evaluation seeds in the same
    order (``(episodes,)``, or ``(runs, episodes)``: averaged over the runs per seed first).

    Returns ``{"iqm", "iqm_low", "iqm_high", "mean", "mean_low", "mean_high", "seeds"}``: IQM(oracle) -
    IQM(rule) and mean(oracle) - mean(rule) with percentile bootstrap CIs.  ``paired`` (default): one draw
    of seed indices serves both agents (module docstring); ``paired=False`` resamples them independently
    (for comparison only: it ignores the pairing and overstates the spread of correlated scores)."""
    o = _per_seed(oracle, "oracle")
    r = _per_seed(rule, "rule")
    if o.shape != r.shape:
        raise ValueError(f"oracle and rule must score the same seeds, got {o.size} and {r.size} of them")
    if isinstance(reps, bool) or not isinstance(reps, int) or reps < 100:
        raise ValueError(f"reps must be an integer >= 100, got {reps!r}")
    if not 0.0 < confidence < 1.0:
        raise ValueError(f"confidence must lie in (0, 1), got {confidence!r}")
    from scipy.stats import trim_mean

    n = o.size
    out = {"iqm": iqm(o) - iqm(r), "mean": float(o.mean() - r.mean()), "seeds": n}
    rng = np.random.default_rng(seed)
    idx_o = rng.integers(0, n, size=(reps, n))
    idx_r = idx_o if paired else rng.integers(0, n, size=(reps, n))
    # rliable's IQM is scipy's 25 % trimmed mean; per bootstrap row here
    d_iqm = trim_mean(o[idx_o], 0.25, axis=1) - trim_mean(r[idx_r], 0.25, axis=1)
    d_mean = o[idx_o].mean(axis=1) - r[idx_r].mean(axis=1)
    q = 100.0 * np.array([(1.0 - confidence) / 2.0, (1.0 + confidence) / 2.0])
    out["iqm_low"], out["iqm_high"] = (float(v) for v in np.percentile(d_iqm, q))
    out["mean_low"], out["mean_high"] = (float(v) for v in np.percentile(d_mean, q))
    return out


def _score_distribution(scores: np.ndarray, taus: np.ndarray) -> np.ndarray:
    """Fraction of all entries of ``scores`` above each ``tau`` (rliable's ``score_distributions``)."""
    x = np.sort(np.asarray(scores, dtype=np.float64).reshape(-1))
    return 1.0 - np.searchsorted(x, np.asarray(taus), side="right") / x.size


def performance_profile_png(
    score_dict: dict[str, np.ndarray],
    path: str | Path,
    title: str = "",
    reps: int = 2_000,
    seed: int = BOOTSTRAP_SEED,
) -> Path | None:
    """rliable's performance profile (fraction of episodes with normalised score > tau, with 95 % bootstrap
    bands) of every agent in ``score_dict`` (name -> ``(runs, episodes)``) as a PNG.  Agents with
    non-finite scores are left out; None (and no file) if none is left."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from rliable import library as rly
    from rliable import plot_utils

    data = {
        k: np.atleast_2d(np.asarray(v, dtype=np.float64)).T
        for k, v in score_dict.items()
        if np.size(v) and np.isfinite(v).all()
    }
    if not data:
        return None
    lo = min(float(v.min()) for v in data.values())
    hi = max(float(v.max()) for v in data.values())
    lo, hi = min(lo, 0.0), max(hi, 1.0)
    taus = np.linspace(lo, hi, 101)
    with _seeded_global_rng(seed):
        # rliable's score distribution (fraction of all entries > tau), vectorised over tau (its own
        # np.vectorize loop costs seconds per agent)
        profiles, cis = rly.create_performance_profile(
            data, taus, reps=reps, custom_profile_func=_score_distribution
        )
    fig, ax = plt.subplots(figsize=(7, 4.5))
    plot_utils.plot_performance_profiles(
        profiles,
        taus,
        performance_profile_cis=cis,
        ax=ax,
        xlabel=r"normalised score $\tau$ (0 = naive, 1 = oracle)",
        ylabel=r"fraction of episodes with score $> \tau$",
        labelsize="medium",
        ticklabelsize="small",
    )
    ax.axvline(0.0, color="0.6", lw=0.8, ls=":")
    ax.axvline(1.0, color="0.6", lw=0.8, ls=":")
    ax.legend(fontsize=7, loc="lower left")
    ax.set_title(title, fontsize=9)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return Path(path)

"""Statistics of the agent benchmark: per-episode normalisation and rliable's interval estimates.

* :func:`normalized_scores`: every episode's return on the task's scale, ``s = (R - S(R_ref)) / (S(R_oracle)
  - S(R_ref))`` with ``S`` the statistic of the aggregate it is reported in (:data:`NORMALISATIONS`: by
  default the IQM columns by IQMs and the mean columns by means, so the reference's normalised IQM and mean
  are exactly 0 and the oracle's exactly 1; issue 19 found the v1 table's IQMs on a mean scale: the naive's
  IQM 0.31-0.41, the oracle's 1.04-1.11) over the task's evaluation seeds (all agents play the same seeds)
  -- as Atari's human-normalised score uses one random and one human reference per game.  The zero
  reference (:func:`reference_plan`) is a competent one: the better, by that same statistic, of the naive
  ramp and "hold the start speed" (the naive ramp touches down on 40 % of RunUpRandomized-v1's draws,
  where holding scores +0.23 on its scale).  Not paired per seed: a per-seed difference ``R - R_naive``
  is dominated by the naive's touchdowns (-100 on a quarter of the seeds), whose trimmed mean then says
  little, and a per-seed denominator ``R_oracle - R_naive`` explodes where both tie (a first version; its
  IQM ranked a rule with a lower mean return first).  If the oracle's statistic does not beat the
  reference's the task has no scale: every score is NaN and ``no_headroom`` is set.
  ``oracle_lost_seeds`` counts the seeds on which the oracle scored below the reference (shocks, for
  instance).
* :func:`interval_estimates`: IQM (and mean) of a score matrix with stratified-bootstrap 95 % CIs, rliable's
  (``rly.get_interval_estimates``: its index draws, aggregates and percentile interval) vectorised over the
  replications (equal to rliable's to rounding, tested; measured 0.04 s for 1 x 100 scores, 0.17 s for 1 x
  200 and 0.8 s for 5 x 200 at 10 000 replications, where rliable's loop took 1.7-3.8 s each).  The matrix
  is ``runs x episodes`` (one row per independent training seed; rules, naive and oracle have one row).
  As rliable's ``(num_runs, num_tasks)`` it is ``(episodes, runs)``: episodes are resampled *within* each
  training seed (the strata), and with two or more training seeds also the seeds themselves (rliable's
  ``task_bootstrap=True``), so the interval of a learned agent includes the seed-to-seed spread.  The
  normalised columns' intervals are the returns' mapped by the task's fixed affine scale
  (:func:`rescale_estimates`): the normalisation's references are fixed, not resampled.
* :func:`paired_headroom`: the headroom of the oracle over a rule (IQM(oracle) - IQM(rule) and the same for
  the means, both on the normalised scale) with a *paired* bootstrap 95 % CI: the evaluation seeds are
  resampled and both agents' scores of a drawn seed go together, so the seed-to-seed variation they share
  (a hard draw is hard for both) cancels; each aggregate's difference on its own scale (IQM scale for
  the IQM headroom, mean scale for the mean headroom).  An agent with several training seeds is first
  averaged over them per evaluation seed (the CI is then over evaluation seeds only, not over training seeds).
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
    "NORMALISATIONS",
    "reference_plan",
    "rescale_estimates",
    "normalized_scores",
    "iqm",
    "interval_estimates",
    "paired_headroom",
    "performance_profile_png",
]

#: a mean oracle-naive margin below this fraction of the returns' size counts as none (rounding)
NO_HEADROOM_REL = 1e-9
#: bootstrap replications (rliable's default is 50 000; :func:`interval_estimates` takes 0.17 s per call
#: for 1 x 200 scores, 0.8 s for 5 x 200: a table of ~40 rows of 200 episodes in well under a minute)
DEFAULT_REPS = 10_000


#: the statistics a score can be normalised by (:func:`normalized_scores`): the references' means or IQMs
REFERENCES = ("mean", "iqm")
#: the table's aggregates: its IQM columns and its mean columns
AGGREGATES = ("iqm", "mean")
#: how the table's normalised columns are scaled (``benchmark_agents --normalise``): ``consistent`` (the
#: default) each aggregate by its own statistic -- the IQM columns by the zero reference's and the oracle's
#: IQMs, the mean columns by their means, so that the reference's normalised IQM and mean are exactly 0 and
#: the oracle's exactly 1; ``mean`` / ``iqm`` both by that one statistic (the v1 table used ``mean``)
NORMALISATIONS = ("consistent", "mean", "iqm")


def _statistic(x: np.ndarray, statistic: str) -> float:
    return iqm(x) if statistic == "iqm" else float(np.mean(x))


def reference_plan(
    candidates: dict[str, np.ndarray], normalise: str = "consistent"
) -> dict[str, dict[str, str]]:
    """The zero of each aggregate's normalisation: per aggregate (``"iqm"``, ``"mean"``) ``{"reference":
    name, "statistic": "iqm" | "mean"}``.  ``candidates``: name -> returns on the task's seeds (the naive
    ramp and "hold the start speed", issue 19: the zero is a competent reference, the better of them);
    ``statistic``: the aggregate's own (``normalise="consistent"``) or the one named; ``reference``: the
    candidate with the highest return statistic (the aggregate being normalised decides: IQM for the IQM
    columns, mean for the mean columns; a tie goes to the first candidate)."""
    if normalise not in NORMALISATIONS:
        raise ValueError(f"normalise must be one of {', '.join(NORMALISATIONS)}, got {normalise!r}")
    if not candidates:
        raise ValueError("candidates: no reference agent to normalise by")
    out = {}
    for agg in AGGREGATES:
        stat = agg if normalise == "consistent" else normalise
        vals = {k: _statistic(np.asarray(v, dtype=np.float64), stat) for k, v in candidates.items()}
        best = max(vals, key=lambda k: (vals[k], -list(vals).index(k)))
        out[agg] = {"reference": best, "statistic": stat}
    return out


def rescale_estimates(est: dict[str, float], zero: float, gap: float) -> dict[str, float]:
    """:func:`interval_estimates` of returns mapped onto a normalised scale ``(R - zero) / gap`` (``gap >
    0``): the IQM, the mean and their percentile bounds commute with an increasing affine map, so this is
    the interval of the normalised scores from the same bootstrap replications (to rounding; tested) --
    one bootstrap per (task, agent) serves the return and both normalised columns."""
    if not (math.isfinite(gap) and gap > 0.0):
        return dict.fromkeys(est, math.nan)
    return {k: (float(v) - zero) / gap for k, v in est.items()}


def normalized_scores(
    returns: np.ndarray, naive: np.ndarray, oracle: np.ndarray, reference: str = "mean"
) -> tuple[np.ndarray, dict]:
    """Per-episode normalised scores of ``returns`` (shape ``(runs, episodes)`` or ``(episodes,)``) on the
    scale of the naive and oracle returns of the same seeds (shape ``(episodes,)`` each).  ``reference``:
    ``"mean"`` (0 = the naive's mean, 1 = the oracle's) or ``"iqm"`` (their IQMs: then the naive's and
    oracle's normalised IQMs are exactly 0 and 1, consistent with an IQM table).

    Returns ``(scores, info)`` with ``scores`` of the shape of ``returns`` and ``info`` =
    ``{"mean_gap", "median_gap", "oracle_lost_seeds", "no_headroom", "statistic", "reference_zero",
    "reference_gap"}`` (module docstring; ``reference_zero`` = the zero reference's statistic,
    ``reference_gap`` = the oracle's minus it: the scale).  ``naive`` is the zero reference's returns (the
    naive ramp's, or whichever :func:`reference_plan` chose)."""
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
        "statistic": reference,
    }
    if reference == "mean" or not gap.size:
        zero, ref_gap = (float(np.mean(n)) if gap.size else math.nan), mean_gap
    else:
        zero = iqm(n)
        ref_gap = iqm(o) - zero
    info["reference_zero"], info["reference_gap"] = zero, ref_gap
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


def _stratified_indices(n_eps: int, n_runs: int, reps: int, task_bootstrap: bool):
    """rliable's ``StratifiedBootstrap`` index draws (``update_indices``) for ``reps`` replications of an
    ``(episodes, runs)`` matrix, from NumPy's global generator in rliable's order: per replication an
    ``(episodes, runs)`` draw of episode indices and, with ``task_bootstrap``, a ``(1, runs)`` draw of run
    indices.  Without the run draws the replications' episode draws are one contiguous stream, so one call
    gives them all (the same numbers as rliable's loop)."""
    if not task_bootstrap:
        idx = np.random.choice(n_eps, (reps, n_eps, n_runs), replace=True)  # noqa: NPY002
        return idx, np.broadcast_to(np.arange(n_runs), (1, 1, n_runs))
    idx = np.empty((reps, n_eps, n_runs), dtype=np.int64)
    tidx = np.empty((reps, 1, n_runs), dtype=np.int64)
    for k in range(reps):  # interleaved draws of two bounds: rliable's order needs the loop (cheap)
        idx[k] = np.random.choice(n_eps, (n_eps, n_runs), replace=True)  # noqa: NPY002
        tidx[k] = np.random.choice(n_runs, (1, n_runs), replace=True)  # noqa: NPY002
    return idx, tidx


#: bootstrap entries aggregated per block (bounds the memory of a (reps, episodes x runs) resample)
_BLOCK_ENTRIES = 4_000_000


def interval_estimates(
    scores: np.ndarray,
    reps: int = DEFAULT_REPS,
    confidence: float = 0.95,
    seed: int = BOOTSTRAP_SEED,
) -> dict[str, float]:
    """IQM and mean of ``scores`` (``(runs, episodes)``, or ``(episodes,)`` for one run) with rliable's
    stratified-bootstrap percentile CIs (module docstring: strata = runs; runs resampled too when >= 2).

    Vectorised: the same index draws as ``rly.get_interval_estimates`` (:func:`_stratified_indices`) and
    the same aggregates (scipy's 25 % trimmed mean, the mean) over all replications at once, and arch's
    percentile interval -- equal to rliable's result to rounding (tested), at about 1/100 of its cost (its
    Python loop over replications took 2-4 s per call for 200 episodes).

    Returns ``{"iqm", "iqm_low", "iqm_high", "mean", "mean_low", "mean_high"}``; all NaN if any score
    is not finite (a task without headroom)."""
    from scipy.stats import trim_mean

    s = np.asarray(scores, dtype=np.float64)
    if s.ndim == 1:
        s = s[None, :]
    if s.ndim != 2 or s.size == 0:
        raise ValueError(f"scores must be a non-empty (runs, episodes) matrix, got shape {s.shape}")
    if isinstance(reps, bool) or not isinstance(reps, int) or reps < 100:
        raise ValueError(f"reps must be an integer >= 100, got {reps!r}")
    if not 0.0 < confidence < 1.0:
        raise ValueError(f"confidence must lie in (0, 1), got {confidence!r}")
    keys = ("iqm", "iqm_low", "iqm_high", "mean", "mean_low", "mean_high")
    if not np.isfinite(s).all():
        return dict.fromkeys(keys, math.nan)
    mat = s.T  # rliable's (num_runs, num_tasks): here (episodes, training runs)
    p_iqm, p_mean = float(trim_mean(mat, 0.25, axis=None)), float(np.mean(mat))
    if mat.shape[0] == 1:  # one episode: no spread to resample
        return dict(zip(keys, (p_iqm, p_iqm, p_iqm, p_mean, p_mean, p_mean), strict=True))
    n_eps, n_runs = mat.shape
    with _seeded_global_rng(seed):
        idx, tidx = _stratified_indices(n_eps, n_runs, reps, n_runs >= 2)
    b_iqm, b_mean = np.empty(reps), np.empty(reps)
    block = max(1, _BLOCK_ENTRIES // mat.size)
    for k in range(0, reps, block):
        t = tidx if tidx.shape[0] == 1 else tidx[k : k + block]
        x = mat[idx[k : k + block], t].reshape(-1, mat.size)
        b_iqm[k : k + block] = trim_mean(x, 0.25, axis=1)
        b_mean[k : k + block] = x.mean(axis=1)
    q = [100.0 * (1.0 - confidence) / 2.0, 100.0 * (1.0 - (1.0 - confidence) / 2.0)]  # arch's percentiles
    lo_i, hi_i = np.percentile(b_iqm, q)
    lo_m, hi_m = np.percentile(b_mean, q)
    return {
        "iqm": p_iqm,
        "iqm_low": float(lo_i),
        "iqm_high": float(hi_i),
        "mean": p_mean,
        "mean_low": float(lo_m),
        "mean_high": float(hi_m),
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
    oracle_mean: np.ndarray | None = None,
    rule_mean: np.ndarray | None = None,
) -> dict[str, float]:
    """Headroom of ``oracle`` over ``rule``: normalised scores on the same evaluation seeds in the same
    order (``(episodes,)``, or ``(runs, episodes)``: averaged over the runs per seed first).
    ``oracle_mean`` / ``rule_mean`` (both or neither): the same episodes on the mean columns' scale (a
    table normalised ``consistent``ly scales its IQM and its mean columns differently); the mean headroom
    and its CI then come from these, on the same resampled seeds as the IQM headroom.

    Returns ``{"iqm", "iqm_low", "iqm_high", "mean", "mean_low", "mean_high", "seeds"}``: IQM(oracle) -
    IQM(rule) and mean(oracle) - mean(rule) with percentile bootstrap CIs.  ``paired`` (default): one draw
    of seed indices serves both agents (module docstring); ``paired=False`` resamples them independently
    (for comparison only: it ignores the pairing and overstates the spread of correlated scores)."""
    o = _per_seed(oracle, "oracle")
    r = _per_seed(rule, "rule")
    if o.shape != r.shape:
        raise ValueError(f"oracle and rule must score the same seeds, got {o.size} and {r.size} of them")
    if (oracle_mean is None) != (rule_mean is None):
        raise ValueError("oracle_mean and rule_mean go together (both or neither)")
    om, rm = o, r
    if oracle_mean is not None:
        om, rm = _per_seed(oracle_mean, "oracle_mean"), _per_seed(rule_mean, "rule_mean")
        if om.shape != o.shape or rm.shape != o.shape:
            raise ValueError("oracle_mean and rule_mean must score the same seeds as oracle and rule")
    if isinstance(reps, bool) or not isinstance(reps, int) or reps < 100:
        raise ValueError(f"reps must be an integer >= 100, got {reps!r}")
    if not 0.0 < confidence < 1.0:
        raise ValueError(f"confidence must lie in (0, 1), got {confidence!r}")
    from scipy.stats import trim_mean

    n = o.size
    out = {"iqm": iqm(o) - iqm(r), "mean": float(om.mean() - rm.mean()), "seeds": n}
    rng = np.random.default_rng(seed)
    idx_o = rng.integers(0, n, size=(reps, n))
    idx_r = idx_o if paired else rng.integers(0, n, size=(reps, n))
    # rliable's IQM is scipy's 25 % trimmed mean; per bootstrap row here
    d_iqm = trim_mean(o[idx_o], 0.25, axis=1) - trim_mean(r[idx_r], 0.25, axis=1)
    d_mean = om[idx_o].mean(axis=1) - rm[idx_r].mean(axis=1)
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
        xlabel=r"normalised score $\tau$ (IQM scale: 0 = the zero reference, naive or hold; 1 = oracle)",
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

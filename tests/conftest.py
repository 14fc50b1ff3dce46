import time

import numpy as np
import pytest

from gfb_env.envs.retired import make_env
from gfb_env.model import GFBModel


def random_admissible_state(model: GFBModel, rng: np.random.Generator) -> np.ndarray:
    """A state with positive pressures and film, moving rotor, deflected foil."""
    L = model.layout
    s = L.centred_state()
    s[L.pressure_slice] = 0.6 + 1.2 * rng.random(L.n_pressure)
    if L.n_foil:
        s[L.foil_slice] = 0.1 * rng.standard_normal(L.n_foil)
    s[L.rotor_slice] = [0.3 * rng.standard_normal(), 0.3 * rng.standard_normal(), 0.05, -0.04]
    assert model.min_film_thickness(s) > 0.05
    return s


@pytest.fixture
def rng():
    return np.random.default_rng(12345)


def assert_refused_at_once(main, argv: list[str], option: str, fragment: str, capsys, out) -> None:
    """``main(argv)`` (the ``gfb`` CLI) refuses: exit code 2, one stderr line ``gfb <cmd>: error: ...``
    naming ``option`` and containing ``fragment``, nothing on stdout, ``out`` not created, within 20 s
    (no heavy work before the refusal)."""
    t0 = time.perf_counter()
    try:
        code = main(argv)
    except SystemExit as exc:
        code = exc.code
    stdout, err = capsys.readouterr()
    lines = err.strip().splitlines()
    assert code == 2 and len(lines) == 1, err
    assert lines[0].startswith(f"gfb {argv[0]}: error:") and option in lines[0] and fragment in lines[0]
    assert stdout == "" and not out.exists()
    assert time.perf_counter() - t0 < 20


def same_value(x, y) -> bool:
    """Exactly the same value, recursively (dicts, tuples, arrays with their dtype and shape, NaN == NaN):
    what "bit for bit" means for observations and infos."""
    if isinstance(x, dict):
        return isinstance(y, dict) and x.keys() == y.keys() and all(same_value(x[k], y[k]) for k in x)
    if isinstance(x, np.ndarray):
        if not (isinstance(y, np.ndarray) and x.dtype == y.dtype and x.shape == y.shape):
            return False
        if x.dtype == object:
            return all(same_value(p, q) for p, q in zip(x.ravel(), y.ravel(), strict=True))
        return np.array_equal(x, y, equal_nan=x.dtype.kind in "fc")
    if isinstance(x, tuple):
        return isinstance(y, tuple) and len(x) == len(y) and all(same_value(p, q) for p, q in zip(x, y))
    if isinstance(x, float) and np.isnan(x):
        return isinstance(y, float) and np.isnan(y)
    return type(x) is type(y) and x == y


def record_short_episode(env_id: str, seed: int, policy=None, episode_steps: int = 12, **kw):
    """(infos, ``hidden_parameters()`` after each, observations, rewards) of a whole episode of
    ``episode_steps`` under ``policy(env.unwrapped)`` (default: the task's scripted expert; a retired v1 id
    through ``make_retired``)."""
    env = make_env(env_id, **{"episode_steps": episode_steps, **kw})
    u = env.unwrapped
    obs, info = env.reset(seed=seed)
    infos, hidden, observations, rewards = [info], [u.hidden_parameters()], [obs], []
    done = False
    while not done:
        a = u.scripted_action() if policy is None else policy(u)
        obs, r, term, trunc, info = env.step(a)
        infos.append(info)
        hidden.append(u.hidden_parameters())
        observations.append(obs)
        rewards.append(r)
        done = term or trunc
    env.close()
    return infos, hidden, observations, rewards

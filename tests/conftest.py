import numpy as np
import pytest

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

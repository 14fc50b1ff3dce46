"""Same inputs, same bits, whether numba compiled the kernels in this process or loaded them from its
on-disk cache (slow: two fresh interpreters with an empty cache folder, ~1-2 minutes).

Found 2026-12-02 (issue 20's worker processes): the v2 plant's 1x solve
(``synchronous._synchronous_update``) called its block factorisation and solve as separately compiled
(cached) functions; a process that loaded them from numba's cache then computed different last bits
(4e-14 on one call) than the process that had compiled them, and a chaotic episode grew that into a
different trajectory: the first run after an install or an edit was not the next run.  The helpers are
now inlined in numba's IR (``inline="always"``), so both processes run the same code.
"""

from __future__ import annotations

import os
import subprocess
import sys

import pytest

SCRIPT = r"""
import numpy as np
from gfb_env.equilibrium import find_equilibrium
from gfb_env.forcing import Unbalance
from gfb_env.model import GFBModel
from gfb_env.synchronous import SynchronousSolver, synchronous_forcing
m = GFBModel("viscoelastic", grid="21x5")
lam, dw = 0.5, 1.0
s = find_equilibrium(m, lam)
solver = SynchronousSolver(m)
solver.start_mode(s, lam, dw)
b = synchronous_forcing(m, Unbalance(0.02, 0.3), lam)
x = solver.update(s, lam, dw, b)
print(x.tobytes().hex(), repr(solver.mode))
"""


@pytest.mark.slow
def test_synchronous_solve_is_the_same_compiled_or_loaded(tmp_path):
    env = {**os.environ, "NUMBA_CACHE_DIR": str(tmp_path / "numba"), "OMP_NUM_THREADS": "1"}
    runs = [
        subprocess.run([sys.executable, "-c", SCRIPT], env=env, capture_output=True, text=True, check=True)
        for _ in range(2)  # the first compiles and writes the cache, the second loads it
    ]
    first, second = (r.stdout.strip().splitlines()[-1] for r in runs)
    assert first == second

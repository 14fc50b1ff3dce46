"""Scripts that reproduce the paper's figures and the project's measurements (`python -m gfb_experiments.X`).

This package is a set of entry points, so it sets single-threaded BLAS defaults on import, before numpy
loads (a library would not touch ``os.environ``; see ``gfb_env._threads``).  A value already set is kept.
"""

import os

for _var in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

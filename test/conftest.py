"""Test-wide settings.

Single-threaded BLAS: our matrices are tiny (states of a modal model), and
OpenBLAS threads on a shared 2-core machine make a 9x9 expm 100x slower.
Set before numpy is imported anywhere.
"""

import os

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
os.environ.setdefault("OMP_NUM_THREADS", "1")

# Hypothesis: random exploration locally; in CI (.ci/run sets the profile) a
# fixed, reproducible set of examples, so that main stays green for a reason.
from hypothesis import settings

# No per-example deadline: a shared CI machine can stall any example (speed is bench/'s job).
settings.register_profile("local", deadline=None)
settings.register_profile("ci", derandomize=True, print_blob=True, deadline=None)
settings.load_profile(os.environ.get("FLEXMOTION_HYPOTHESIS_PROFILE", "local"))

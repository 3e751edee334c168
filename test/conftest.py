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


import pytest  # noqa: E402  (after the environment above, like hypothesis)


@pytest.fixture
def spy(monkeypatch):
    """Record the calls of a real function without changing what it does.

    ``calls = spy(owner, "name", record)`` replaces ``owner.name`` (a module function or a class's method) by a
    wrapper that appends ``record(*args, **kwargs)`` to ``calls`` (default: 1 per call) and then calls the real
    one; the work-bound tests count expm samples, exact runs and LP sizes with it.  ``monkeypatch`` undoes it.
    """

    def install(owner, name, record=None):
        real = getattr(owner, name)
        calls = []

        def recording(*args, **kwargs):
            calls.append(1 if record is None else record(*args, **kwargs))
            return real(*args, **kwargs)

        monkeypatch.setattr(owner, name, recording)
        return calls

    return install


@pytest.fixture(scope="session", autouse=True)
def _compiled_kernels():
    """Compile numba's kernels (or load them from its cache) once, before any test, so that no test's
    timing or timeout pays the first compilation (seconds on a fresh clone), and forked planners inherit them."""
    from flexmotion_ros.core.kernels import warm_up

    warm_up()

"""Skip numba's BLAS probe in processes that only run this package's kernels.

The first time numba loads a cached function it imports ``numba.np.arraymath``, which probes
for BLAS by importing ``scipy.linalg`` when SciPy is installed: 0.3 to 0.5 s, about a third
of a warm ``dice-sweep roll`` (found with cProfile of ``SweepJob.warm_up``). The kernels here
use no BLAS (no np.dot, no np.linalg), so the CLI's ``roll`` and ``sweep`` commands tell
numba there is none. Not done on import of the library: in a user's own process, numba code
of theirs may need BLAS.
"""

import importlib.abc
import sys

_BLOCKED = ("scipy.linalg", "scipy.linalg.cython_blas")


class _NoScipyLinalg(importlib.abc.MetaPathFinder):
    def find_spec(self, name, path=None, target=None):
        if name in _BLOCKED:
            raise ImportError(f"{name}: not imported while numba probes for BLAS (dice_sweep fast start)")
        return None


def skip_numba_blas_probe() -> bool:
    """Import numba's array-math registry with scipy.linalg hidden; True if that took effect.

    Does nothing (False) when the registry or scipy.linalg is imported already.
    """
    if "numba.np.arraymath" in sys.modules or "scipy.linalg" in sys.modules:
        return False
    finder = _NoScipyLinalg()
    sys.meta_path.insert(0, finder)
    try:
        import numba.np.arraymath  # noqa: F401  (sets its _HAVE_BLAS = False)
    finally:
        sys.meta_path.remove(finder)
    return True

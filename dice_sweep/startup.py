"""What a process does before and while it loads the kernels (issue 16): where numba caches
them, when a compile is announced, and skipping numba's BLAS probe in the CLI.

Where numba caches the kernels, and what makes a cached copy current
--------------------------------------------------------------------
numba's own locators key each function's cache on that function's file only, so a change in
``flight.py`` left ``kernel.roll_batch`` loading a stale machine-code copy that still called
the old flight code (seen while developing the kernel); and with ``NUMBA_CACHE_DIR`` the
cache of a file sits under a hash of its absolute directory, so a fresh checkout elsewhere (a
CI job in a new build directory) never finds it. The locator below, installed before the
kernels are defined, keys every kernel's cache on one hash of all physics sources and puts
it in one directory that does not depend on where the package lives:

- ``$NUMBA_CACHE_DIR/dice_sweep_physics`` when ``NUMBA_CACHE_DIR`` is set (what a CI job
  keeps between runs: docs/cold_start.md, "Keeping the compiled kernel between CI jobs");
- else ``dice_sweep/physics/__pycache__`` when writable, else numba's user-wide cache
  directory.

A cache written from other sources is ignored and overwritten, never loaded.

Skipping numba's BLAS probe in processes that only run this package's kernels
-----------------------------------------------------------------------------
The first time numba loads a cached function it imports ``numba.np.arraymath``, which probes
for BLAS by importing ``scipy.linalg`` when SciPy is installed: 0.3 to 0.5 s, about a third
of a warm ``dice-sweep roll`` (found with cProfile of ``SweepJob.warm_up``). The kernels here
use no BLAS (no np.dot, no np.linalg), so the CLI's ``roll`` and ``sweep`` commands tell
numba there is none; likewise numba's cffi support, whose ``cffi.FFI()`` imports a C parser
(30 ms of CPU, ``python -X importtime``; docs/dev/sweep_time.md). Not done on import of the
library: in a user's own process, numba code of theirs may need BLAS or cffi.
"""

import functools
import hashlib
import importlib.abc
import os
import sys
from pathlib import Path

_PHYSICS_DIR = Path(__file__).resolve().parent / "physics"
CACHE_SUBDIR = "dice_sweep_physics"


def source_digest():
    """SHA-256 (hex) of every physics source file, by name and content, and of what the kernels
    compile in from outside physics/: the effect registry's kernel slots and the codes of the
    config's choices (adding an effect renumbers the slots after it without touching a
    physics file; a cache keyed on the physics files alone would index the old layout)."""
    from dice_sweep import config, effects

    digest = hashlib.sha256()
    for path in sorted(_PHYSICS_DIR.glob("*.py")):
        digest.update(path.name.encode())
        digest.update(path.read_bytes())
    layout = [(key.dotted, key.slot, key.length, key.choices) for keys in effects.config_key_specs().values() for key in keys.values()]
    digest.update(repr((layout, config.CONTACT_MODELS, config.INTEGRATOR_METHODS)).encode())
    return digest.hexdigest()


@functools.cache
def _process_digest():
    return source_digest()  # once per process: the sources do not change under a running kernel


def cache_directories():
    """Directories to try for the kernels' cache, in order (see the module)."""
    from numba.core import config
    from numba.misc.appdirs import AppDirs

    if config.CACHE_DIR:
        return [os.path.join(config.CACHE_DIR, CACHE_SUBDIR)]
    user_wide = AppDirs(appname="numba", appauthor=False).user_cache_dir
    return [str(_PHYSICS_DIR / "__pycache__"), os.path.join(user_wide, CACHE_SUBDIR)]


_writable = set()  # cache directories this process has created and written a test file in


def _locator_class():
    from numba.core import caching

    class SourcesLocator(caching._CacheLocator):
        """numba cache locator of dice_sweep.physics (see the module)."""

        def __init__(self, py_func, cache_path):
            self._lineno = py_func.__code__.co_firstlineno
            self._cache_path = cache_path

        def get_cache_path(self):
            return self._cache_path

        def get_source_stamp(self):
            return _process_digest()

        def get_disambiguator(self):
            return str(self._lineno)

        @classmethod
        def from_function(cls, py_func, py_file):
            if not getattr(py_func, "__module__", "").startswith("dice_sweep.physics."):  # only the kernels
                return None
            for path in cache_directories():
                locator = cls(py_func, path)
                if path not in _writable:  # tested once per process, not once per kernel (about 130)
                    try:
                        locator.ensure_cache_path()
                    except OSError:
                        continue
                    _writable.add(path)
                return locator
            return None  # nowhere writable: numba's own locators decide

    return SourcesLocator


def install_locator():
    """Make numba locate the caches of dice_sweep.physics with the locator above; other
    functions keep numba's own. Safe to call twice; never fails (an unknown numba layout
    leaves numba's defaults)."""
    try:
        from numba.core import caching

        impl = getattr(caching, "CacheImpl", None) or caching._CacheImpl
        classes = impl._locator_classes
        if not any(getattr(c, "__name__", "") == "SourcesLocator" for c in classes):
            impl._locator_classes = [_locator_class(), *classes]
    except (ImportError, AttributeError):
        pass


# A cold compile on the project's 2-core machine: about 46 s for a first roll or sweep that compiles
# when it is quiet (docs/cold_start.md, "compile forced"); slower or loaded machines more.
COLD_COMPILE_SECONDS = (30, 50)


_notified = []  # the callback registered in this process, if any


def notify_first_compile(callback):
    """Call ``callback()`` once, when numba first starts compiling a function of this package
    (not on loading one from the cache); one such callback per process. Uses numba's compile
    events (numba.core.event), which fire only on a cache miss."""
    from numba.core import event

    if _notified:
        return
    _notified.append(callback)

    class _FirstCompile(event.Listener):
        done = False

        def on_start(self, ev):
            dispatcher = ev.data.get("dispatcher") if isinstance(ev.data, dict) else None
            module = getattr(getattr(dispatcher, "py_func", None), "__module__", "") or ""
            if not self.done and module.startswith("dice_sweep."):
                self.done = True
                callback()

        def on_end(self, ev):
            pass

    event.register("numba:compile", _FirstCompile())

# numba module -> what it imports only to support what the kernels do not use
_SKIPPED = {
    "numba": ("scipy",),  # numba's import checks SciPy's version (SciPy >= 1.0): 8-9 ms of CPU to import it
    "numba.np.arraymath": ("scipy.linalg", "scipy.linalg.cython_blas"),  # the BLAS probe
    "numba.core.typing.cffi_utils": ("cffi",),  # cffi.FFI() parses C declarations: 30 ms of CPU
}


class _Hidden(importlib.abc.MetaPathFinder):
    # the top package too: importing scipy.linalg imports scipy first (8-9 ms of CPU)
    def __init__(self, names):
        self.names = {*names, *(name.partition(".")[0] for name in names)}

    def find_spec(self, name, path=None, target=None):
        if name in self.names:
            raise ImportError(f"{name}: not imported while numba looks for it (dice_sweep fast start)")
        return None


def skip_numba_blas_probe() -> bool:
    """Import numba with scipy hidden (its version check), numba's array-math registry with
    scipy hidden (the BLAS probe), and its cffi support with cffi hidden; True if the BLAS
    probe was skipped.

    Each does nothing when the numba module or the hidden one is imported already (False for
    the BLAS probe). The kernels call no BLAS and no cffi function.
    """
    skipped = {}
    for module, hidden in _SKIPPED.items():
        skipped[module] = module not in sys.modules and not any(name in sys.modules for name in hidden)
        if not skipped[module]:
            continue
        finder = _Hidden(hidden)
        sys.meta_path.insert(0, finder)
        try:
            importlib.import_module(module)  # numba.np.arraymath: _HAVE_BLAS = False; cffi_utils: SUPPORTED = False
        finally:
            sys.meta_path.remove(finder)
    return skipped["numba.np.arraymath"]

"""Which engine runs the kernels: numba's compiled code, or the same source as plain Python.

With an empty numba cache (a fresh machine, every CI job that does not keep the cache) the
first call of a kernel compiles it: 10-20 s on a 2-core machine. The kernels are plain loops
over floats and small arrays, so the interpreter can run the very same functions: 100-1000
times slower than compiled code, but with nothing to compile. Their results are bit for bit
those of the compiled kernel (IEEE arithmetic and the same libm; tests/test_engine.py checks
the golden maps), so which engine ran a roll never shows in its result.

The rule (:func:`sweep_engine`): a kernel numba has compiled or cached runs compiled; so does
any work the plain engine would take longer on than a compile. Small cold work, a single
roll or a first small sweep, runs plain and compiles nothing. Set ``DICE_SWEEP_ENGINE`` to
``numba`` or ``plain`` to force one.
"""

from __future__ import annotations

import functools
import math
import os
import time
import types

import numpy as np

ENGINE_NUMBA = "numba"
ENGINE_PLAIN = "plain"
ENGINES = (ENGINE_NUMBA, ENGINE_PLAIN)
ENGINE_VARIABLE = "DICE_SWEEP_ENGINE"

# What a cold compile of the sweep kernel costs on the project's 2-core machine (scripts/bench.py,
# "cold" rows): work the plain engine would finish sooner than this runs plain.
COMPILE_SECONDS = 46.0  # median of 3 compile-forced rolls at load 1.1-2.1 (docs/cold_start.md); 43 s before issue 31's mixture law, 33's hop step, pivot_ode_flat and wall-chatter rule, 36 s before issue 33's closed-form slide, hinge and inlined impact law, 31 s before issue 33's ladder phase and pivot events, 23 s before issues 31 and 33
PROBE_SECONDS = 0.3  # at most this long timing plain rolls to estimate the plain engine's speed
PROBE_ROLLS = 32  # starts spread over the work, timed one by one



def forced_engine() -> str | None:
    """The engine ``DICE_SWEEP_ENGINE`` asks for, or None; anything else is an error."""
    from dice_sweep.errors import DiceSweepError

    value = os.environ.get(ENGINE_VARIABLE, "").strip()
    if not value:
        return None
    if value not in ENGINES:
        raise DiceSweepError(f"{ENGINE_VARIABLE}={value!r}: allowed values are {', '.join(ENGINES)} (or unset)")
    return value


@functools.cache
def _plain_functions() -> dict:
    """Every jitted function of dice_sweep.physics -> its plain-Python twin.

    A twin is a new function object on the same code object, whose globals are a copy of its
    module's globals with every jitted function replaced by its twin: calls between kernels
    stay in the interpreter instead of reaching numba's dispatcher (which would compile).
    """
    import importlib
    import pkgutil

    from numba.core.dispatcher import Dispatcher

    import dice_sweep.physics as physics

    # every module of the package: a new kernel module (exact_impact.py was one) needs no entry here
    names = [info.name for info in pkgutil.iter_modules(physics.__path__)]
    modules = [importlib.import_module(f"dice_sweep.physics.{name}") for name in names]
    namespaces = {module.__name__: dict(vars(module)) for module in modules}
    twins = {}
    for module in modules:
        for value in vars(module).values():
            if isinstance(value, Dispatcher) and value not in twins:
                py = value.py_func
                twin = types.FunctionType(py.__code__, namespaces[py.__module__], py.__name__, py.__defaults__, py.__closure__)
                twin.__qualname__ = py.__qualname__
                twin.__doc__ = py.__doc__
                twins[value] = twin
    for namespace in namespaces.values():
        for name, value in namespace.items():
            if isinstance(value, Dispatcher):
                namespace[name] = twins[value]
    return twins


def plain(kernel):
    """The plain-Python twin of a jitted kernel of dice_sweep.physics."""
    return _plain_functions()[kernel]


def compiled_ready(kernel, args) -> bool:
    """True if numba can run ``kernel`` on ``args`` without compiling: compiled in this process
    or found in its on-disk cache (an index entry for these argument types, from the current
    sources). Unknown (numba's internals changed): True, so that nothing changes."""
    try:
        signature = tuple(kernel.typeof_pyval(a) for a in args)
        if signature in kernel.overloads:
            return True
        cache = kernel._cache
        index = cache._cache_file._load_index()  # {} when the sources changed since it was written
        return cache._index_key(signature, kernel.targetctx.codegen()) in index
    except Exception:  # noqa: BLE001  (private numba API: any failure means "do as before")
        return True


def call_engine(kernel, args) -> str:
    """Engine for one call of ``kernel`` (a single roll, one path sampled): compiled when
    ready, else plain (one roll takes milliseconds to a fraction of a second plain)."""
    forced = forced_engine()
    if forced is not None:
        return forced
    return ENGINE_NUMBA if compiled_ready(kernel, args) else ENGINE_PLAIN


def run(kernel, engine: str, *args):
    """Call ``kernel`` with ``args`` on ``engine``.

    The plain engine gets the parameter vectors (``fpar``, ``ipar``: the first two arguments
    of every entry kernel) as Python lists: arithmetic on Python floats is IEEE's, as on numpy
    scalars, and 1.5 times faster in the interpreter (fig09's rolls: 17.4 -> 11.8 ms).
    """
    if engine == ENGINE_PLAIN:
        fpar, ipar, *rest = args
        try:
            with np.errstate(all="ignore"):  # numpy scalars warn where compiled code is silent
                return plain(kernel)(fpar.tolist(), ipar.tolist(), *rest)
        except (ArithmeticError, ValueError):
            pass  # a domain error (math.sqrt(-0.1)) that compiled code answers with NaN: run that
    return kernel(*args)


def probe_seconds_per_roll(roll_plain, states: np.ndarray) -> float:
    """Plain-engine seconds per roll, timed on up to PROBE_ROLLS of ``states`` spread over
    them, stopping after PROBE_SECONDS. ``roll_plain(states)`` rolls a batch plainly."""
    picks = np.unique(np.linspace(0, len(states) - 1, min(PROBE_ROLLS, len(states))).astype(np.int64))
    started = time.perf_counter()
    done = 0
    for index in picks:
        roll_plain(states[index : index + 1])
        done += 1
        if time.perf_counter() - started > PROBE_SECONDS:
            break
    return (time.perf_counter() - started) / done


def sweep_engine(kernel, args, roll_plain, states, rolls: int, workers: int) -> str:
    """Engine for ``rolls`` rolls like ``states`` over ``workers`` processes.

    Compiled when numba has ``kernel`` ready for ``args``; otherwise plain if its estimated
    time (from a probe of a few plain rolls) is below a compile's, COMPILE_SECONDS.
    ``states`` may be a callable returning them, called only if a probe is needed.
    """
    forced = forced_engine()
    if forced is not None:
        return forced
    if rolls == 0 or compiled_ready(kernel, args):
        return ENGINE_NUMBA
    try:
        per_roll = probe_seconds_per_roll(roll_plain, states() if callable(states) else states)
    except Exception:  # noqa: BLE001  (e.g. a domain error the compiled code would not raise)
        return ENGINE_NUMBA
    plain_seconds = per_roll * rolls / max(1, workers)
    return ENGINE_PLAIN if math.isfinite(plain_seconds) and plain_seconds < COMPILE_SECONDS else ENGINE_NUMBA

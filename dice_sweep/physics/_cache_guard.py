"""Drop numba's on-disk cache when any physics source changed.

numba's ``cache=True`` keys each function's cache on that function's own file only, so a
change in ``flight.py`` leaves ``kernel.roll_batch`` loading a stale machine-code copy that
still calls the old flight code (seen while developing the kernel). A stamp with the hash of
all physics sources, checked once per process at import, removes such stale entries.
"""

import hashlib
from pathlib import Path

_PHYSICS_DIR = Path(__file__).resolve().parent
_STAMP_NAME = "dice_sweep_sources.sha256"


def source_digest():
    digest = hashlib.sha256()
    for path in sorted(_PHYSICS_DIR.glob("*.py")):
        digest.update(path.name.encode())
        digest.update(path.read_bytes())
    return digest.hexdigest()


def drop_stale_cache():
    """Remove cached kernels built from other sources; never fails (a read-only install
    leaves numba to use its own user cache directory)."""
    cache_dir = _PHYSICS_DIR / "__pycache__"
    stamp = cache_dir / _STAMP_NAME
    digest = source_digest()
    try:
        if stamp.exists() and stamp.read_text() == digest:
            return
        if cache_dir.is_dir():
            for entry in cache_dir.iterdir():
                if entry.suffix in (".nbi", ".nbc"):
                    entry.unlink(missing_ok=True)
        cache_dir.mkdir(exist_ok=True)
        tmp = stamp.with_suffix(".tmp")
        tmp.write_text(digest)
        tmp.replace(stamp)
    except OSError:
        pass


# A cold compile on the project's 2-core machine: 20-23 s for a first roll or sweep
# (docs/performance.md, `dice-sweep roll` with an empty numba cache); slower machines more.
COLD_COMPILE_SECONDS = (15, 40)


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

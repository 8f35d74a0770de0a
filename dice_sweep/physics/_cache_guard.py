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

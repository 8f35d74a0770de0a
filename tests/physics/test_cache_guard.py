"""The numba cache is dropped when a physics source changes (stale-cache pitfall)."""

from dice_sweep.physics import _cache_guard


def test_stale_cache_entries_are_removed(tmp_path, monkeypatch):
    src = tmp_path / "physics"
    src.mkdir()
    (src / "flight.py").write_text("x = 1\n")
    monkeypatch.setattr(_cache_guard, "_PHYSICS_DIR", src)
    _cache_guard.drop_stale_cache()
    cache = src / "__pycache__"
    entry = cache / "kernel.roll_batch-1.py311.nbi"
    entry.write_bytes(b"old")
    _cache_guard.drop_stale_cache()
    assert entry.exists()  # sources unchanged: cache kept
    (src / "flight.py").write_text("x = 2\n")
    _cache_guard.drop_stale_cache()
    assert not entry.exists()  # a source changed: stale entry gone

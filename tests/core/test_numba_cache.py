"""The numba cache of every compiled source is dropped when any one of them changes (numba itself checks
only the file defining each function, so an edit of an inlined callee would run stale machine code)."""

import re
from pathlib import Path

from gfb_env import _numba_cache as nc


def _fake_package(root: Path) -> None:
    for rel in nc.COMPILED_SOURCES:
        f = root / rel
        f.parent.mkdir(parents=True, exist_ok=True)
        f.write_text(f"# {rel}\n")
        cache = f.parent / "__pycache__"
        cache.mkdir(exist_ok=True)
        (cache / f"{f.stem}.fn-10.py311.nbi").write_bytes(b"index")
        (cache / f"{f.stem}.fn-10.py311.1.nbc").write_bytes(b"code")


def _caches(root: Path) -> list[Path]:
    return sorted(p for p in root.rglob("*") if p.suffix in (".nbi", ".nbc"))


def test_an_edit_of_one_compiled_source_drops_every_cache(tmp_path):
    _fake_package(tmp_path)
    (tmp_path / "__pycache__").mkdir(exist_ok=True)
    (tmp_path / "__pycache__" / "other.cpython-311.pyc").write_bytes(b"pyc")
    assert nc.invalidate_stale_caches(tmp_path) and _caches(tmp_path) == []  # no stamp yet: unknown origin
    assert (tmp_path / "__pycache__" / "other.cpython-311.pyc").exists()  # only numba's files go
    _fake_package(tmp_path)  # numba writes its caches again
    assert not nc.invalidate_stale_caches(tmp_path)  # sources unchanged: the caches stay
    assert len(_caches(tmp_path)) == 2 * len(nc.COMPILED_SOURCES)
    (tmp_path / "integrator" / "controller.py").write_text("# safety = 0.8 -> 0.79\n")  # an inlined callee
    assert nc.invalidate_stale_caches(tmp_path)
    assert _caches(tmp_path) == []  # the callers' caches (stages, batch) went too


def test_the_package_lists_every_file_that_compiles_cached_code():
    root = Path(nc.__file__).resolve().parent
    cached = {
        str(p.relative_to(root))
        for p in root.rglob("*.py")
        if re.search(r"@(numba\.)?n?jit\([^)]*cache=True", p.read_text())
    }
    assert cached <= set(nc.COMPILED_SOURCES), cached - set(nc.COMPILED_SOURCES)

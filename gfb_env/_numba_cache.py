"""Numba's on-disk cache kept honest across files.

numba's ``cache=True`` keys a compiled function's cache on the file that defines it (its path, size and
modification time), not on the files of the functions it inlines or calls.  The integrator's compiled
loop (``integrator/stages.py``) and batch kernels (``integrator/batch.py``) call the step-size controller,
the argument groups, the model's kernels (``_kernels.py``) and the forcing (``forcing.py``): after an edit
of one of those alone, the cached machine code of the callers would run the old code silently.  So, once
per import of :mod:`gfb_env` (which imports this module first: the import runs it),
:func:`invalidate_stale_caches` hashes every source file that compiled code
is built from (:data:`COMPILED_SOURCES`, a few hundred kB: well under a millisecond) and, when the digest
differs from the one stamped beside the caches, deletes the numba cache files of all of them, so that
everything is recompiled together.  Best effort: an unwritable installation (numba then caches in its
user-wide folder, or ``NUMBA_CACHE_DIR``) is left alone.
"""

from __future__ import annotations

import hashlib
from pathlib import Path

#: the package's source files from which numba compiles cached code (relative to the package folder)
COMPILED_SOURCES = (
    "_kernels.py",
    "forcing.py",
    "integrator/arguments.py",
    "integrator/batch.py",
    "integrator/controller.py",
    "integrator/results.py",
    "integrator/stages.py",
    "analysis/periodic.py",
    "synchronous.py",
    "machine/_monitor_kernels.py",
    "envs/_superposition_kernels.py",
)

#: the stamp file (in the package's ``__pycache__``): the digest of the sources the caches were made from
STAMP_NAME = "gfb_numba_sources.sha256"


def sources_digest(root: Path, sources: tuple[str, ...] = COMPILED_SOURCES) -> str:
    """SHA-256 of the names and bytes of ``sources`` under ``root`` (a missing file counts as empty)."""
    h = hashlib.sha256()
    for rel in sources:
        h.update(rel.encode() + b"\0")
        try:
            h.update((root / rel).read_bytes())
        except OSError:
            h.update(b"<missing>")
    return h.hexdigest()


#: the package folder
PACKAGE_DIR = Path(__file__).resolve().parent


def invalidate_stale_caches(root: Path = PACKAGE_DIR, sources: tuple[str, ...] = COMPILED_SOURCES) -> bool:
    """Delete the numba cache files (``__pycache__/<module>.*.nbi`` / ``.nbc``) of every file of
    ``sources`` if any of them changed since the caches were stamped; returns True if it deleted."""
    digest = sources_digest(root, sources)
    stamp = root / "__pycache__" / STAMP_NAME
    try:
        if stamp.read_text().strip() == digest:
            return False
    except OSError:
        pass
    removed = False
    try:
        for rel in sources:
            src = root / rel
            for pattern in (f"{src.stem}.*.nbi", f"{src.stem}.*.nbc"):
                for f in (src.parent / "__pycache__").glob(pattern):
                    f.unlink(missing_ok=True)
                    removed = True
        stamp.parent.mkdir(exist_ok=True)
        stamp.write_text(digest + "\n")
    except OSError:  # a read-only installation: numba caches elsewhere (or not at all)
        return removed
    return removed


invalidate_stale_caches()

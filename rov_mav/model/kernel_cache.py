"""Numba cache locators for the kernels: a cached kernel is fresh only while every kernel source is unchanged.

Numba checks a cached function against its own file only, while the offline closed loop (offline/loop_kernel.py)
inlines the model and the laws from other files: after an edit to a law, the cached loop would go on running the
law's old code. These locators put the caches where Numba's own would (the user's NUMBA_CACHE_DIR, the package's
__pycache__, the user-wide cache) but stamp them with one digest of all kernel sources, so that an edit to any of
them recompiles every kernel once. Functions outside the kernel layers keep Numba's own locators.
"""

from __future__ import annotations

import functools
import hashlib
import re
from pathlib import Path

from numba import config
from numba.core import caching

PACKAGE = Path(__file__).resolve().parents[1]
KERNEL_LAYERS = ("model", "control", "offline")
# A line that makes a compiled function: one of kernel.py's decorators, or Numba's own.
_DEFINES_KERNEL = re.compile(rb"^@(compiled|inlined|compiled_loop|allocating)\b|njit\(", re.MULTILINE)
NUMBA_LOCATORS = ("UserProvidedCacheLocator", "InTreeCacheLocator", "UserWideCacheLocator", "IPythonCacheLocator",
                  "ZipCacheLocator")


def kernel_sources() -> list[Path]:
    """The modules of the kernel layers that define compiled functions, sorted."""
    return sorted(p for layer in KERNEL_LAYERS for p in (PACKAGE / layer).glob("*.py")
                  if _DEFINES_KERNEL.search(p.read_bytes()))


@functools.cache
def sources_digest() -> str:
    """SHA-256 (hex) over the kernel sources' names and contents, as they are when first asked in this process."""
    digest = hashlib.sha256()
    for path in kernel_sources():
        digest.update(path.relative_to(PACKAGE).as_posix().encode() + b"\0" + path.read_bytes() + b"\0")
    return digest.hexdigest()


def _in_kernel_layers(py_file: str) -> bool:
    path = Path(py_file).resolve()
    return any(path.parent == PACKAGE / layer for layer in KERNEL_LAYERS)


class _AllKernelSourcesStamp:
    """Mixin over a Numba locator: the kernel layers' functions only, stamped with sources_digest()."""

    def get_source_stamp(self):
        return sources_digest()

    @classmethod
    def from_function(cls, py_func, py_file):
        if not _in_kernel_layers(py_file):
            return None
        return super().from_function(py_func, py_file)


class UserProvided(_AllKernelSourcesStamp, caching.UserProvidedCacheLocator):
    """NUMBA_CACHE_DIR, when set."""


class InTree(_AllKernelSourcesStamp, caching.InTreeCacheLocator):
    """The package's __pycache__, when writable."""


class UserWide(_AllKernelSourcesStamp, caching.UserWideCacheLocator):
    """The user's cache directory."""


def install() -> None:
    """Put these locators first in Numba's search (before any kernel is decorated); idempotent."""
    ours = [f"{__name__}.{cls.__name__}" for cls in (UserProvided, InTree, UserWide)]
    rest = [name.strip() for name in (config.CACHE_LOCATOR_CLASSES or ",".join(NUMBA_LOCATORS)).split(",")
            if name.strip() and name.strip() not in ours]
    config.CACHE_LOCATOR_CLASSES = ",".join(ours + rest)

"""The kernels' cache is stale after an edit to any kernel source, not only to the cached function's own file."""

from __future__ import annotations

import shutil

from rov_mav.model import kernel_cache
from rov_mav.offline import loop_kernel


def test_the_closed_loop_is_cached_under_the_digest_of_all_kernel_sources():
    locator = loop_kernel.simulate_batch._cache._impl.locator
    assert isinstance(locator, kernel_cache._AllKernelSourcesStamp)
    assert locator.get_source_stamp() == kernel_cache.sources_digest()
    names = {p.relative_to(kernel_cache.PACKAGE).as_posix() for p in kernel_cache.kernel_sources()}
    assert {"model/kernel.py", "control/law_kernel.py", "control/ismc.py", "offline/loop_kernel.py"} <= names


def test_an_edit_to_a_law_changes_the_digest_and_an_edit_elsewhere_does_not(tmp_path, monkeypatch):
    for layer in kernel_cache.KERNEL_LAYERS:
        shutil.copytree(kernel_cache.PACKAGE / layer, tmp_path / layer, ignore=shutil.ignore_patterns("__pycache__"))
    monkeypatch.setattr(kernel_cache, "PACKAGE", tmp_path)

    def digest():
        kernel_cache.sources_digest.cache_clear()
        return kernel_cache.sources_digest()

    try:
        before = digest()
        bench = tmp_path / "offline" / "bench.py"           # no compiled function in it
        bench.write_text(bench.read_text() + "\n# an edit\n")
        assert digest() == before
        law = tmp_path / "control" / "smc.py"
        law.write_text(law.read_text().replace("min(max(x, -1.0), 1.0)", "min(max(x, -2.0), 2.0)"))
        assert digest() != before
    finally:
        kernel_cache.sources_digest.cache_clear()

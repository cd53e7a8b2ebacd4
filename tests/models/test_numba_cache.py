"""numba's cache is keyed by the sources of the whole package, so a changed callee is never served stale."""

import numba

from models import numba_cache_dir


def test_the_cache_folder_changes_with_any_source_file(tmp_path):
    pkg = tmp_path / "pkg"
    (pkg / "sub").mkdir(parents=True)
    (pkg / "a.py").write_text("x = 1\n")
    (pkg / "sub" / "b.py").write_text("y = 2\n")
    first = numba_cache_dir(pkg, tmp_path / "cache")
    assert first.parent == tmp_path / "cache"
    assert numba_cache_dir(pkg, tmp_path / "cache") == first  # same sources, same folder
    (pkg / "sub" / "b.py").write_text("y = 3\n")  # a callee in another file changes
    second = numba_cache_dir(pkg, tmp_path / "cache")
    assert second != first
    (pkg / "sub" / "b.py").rename(pkg / "b2.py")  # a move changes it too
    assert numba_cache_dir(pkg, tmp_path / "cache") not in (first, second)


def test_numba_uses_the_folder_of_these_sources():
    from pathlib import Path

    from models.bayes.delayed_op import warm_samples  # a cache=True kernel

    assert Path(numba.config.CACHE_DIR).name == numba_cache_dir().name  # ~/.cache, or the temp dir if unwritable
    assert warm_samples(0.5, 0.1) > 0
    cached = [p.name for p in Path(numba.config.CACHE_DIR).rglob("*.nbi")]
    assert any(name.startswith("delayed_op.warm_samples") for name in cached), cached

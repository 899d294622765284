"""The one in-memory cache type (appell._cache.Cache, issue 45 "one cache type"): bounded,
least recently used dropped first, keys by identity where asked, safe to share between
threads; and the module-level caches of the package are all of that type.

Source of truth: the definition of least-recently-used eviction (an entry read or written
is the newest; the oldest goes when a new entry exceeds the bound), checked step by step
against a plain list kept in that order."""

from __future__ import annotations

import random
import threading

import pytest

from appell._cache import Cache


def test_the_cache_is_bounded_and_drops_the_least_recently_used():
    cache = Cache(3)
    for key in "abc":
        cache.put(key, key.upper())
    assert cache.get("a") == "A"  # 'a' is now the newest: order b, c, a
    cache.put("d", "D")
    assert "b" not in cache and cache.keys() == ["c", "a", "d"]
    assert len(cache) == 3 and cache.get("b") is None and cache.get("b", 0) == 0


def test_a_random_sequence_matches_a_list_kept_in_lru_order():
    rng = random.Random(45)
    cache, order = Cache(5), []  # order: the keys, least recently used first
    for _ in range(2000):
        key = rng.randrange(12)
        if rng.random() < 0.5:
            found = cache.get(key)
            assert found == (key * 10 if key in order else None)
            if key in order:
                order.remove(key)
                order.append(key)
        else:
            cache.put(key, key * 10)
            if key in order:
                order.remove(key)
            order.append(key)
            del order[:-5]
        assert cache.keys() == order


def test_put_keeps_the_first_value_and_get_or_make_makes_once():
    cache = Cache(2)
    assert cache.put("k", 1) == 1 and cache.put("k", 2) == 1
    made = []
    assert cache.get_or_make("m", lambda: made.append(1) or "value") == "value"
    assert cache.get_or_make("m", lambda: made.append(1) or "other") == "value"
    assert made == [1]
    assert cache.pop("m") == "value" and "m" not in cache and cache.pop("m", "gone") == "gone"
    cache.clear()
    assert len(cache) == 0
    with pytest.raises(ValueError):
        Cache(0)


class _Unhashable:
    __hash__ = None  # as costly to hash as a derivation: identity keys never hash it

    def __eq__(self, other):
        return True  # equal to everything: only identity tells two apart


def test_identity_keys_tell_equal_objects_apart_and_hold_their_key():
    cache = Cache(2, identity=True)
    a, b = _Unhashable(), _Unhashable()
    cache.put(a, "a")
    assert cache.get(a) == "a" and cache.get(b) is None and b not in cache and a in cache
    cache.put(b, "b")
    assert cache.keys()[0] is a and cache.keys()[1] is b
    cache.put(_Unhashable(), "temporary")
    assert len(cache) == 2 and a not in cache and cache.get(b) == "b"


def test_threads_share_one_cache_without_losing_its_bound_or_its_order():
    cache = Cache(16)
    errors = []

    def work(seed):
        rng = random.Random(seed)
        try:
            for _ in range(5000):
                key = rng.randrange(40)
                value = cache.get_or_make(key, lambda key=key: key * 2)
                if value != key * 2:
                    errors.append((key, value))
                if rng.random() < 0.05:
                    cache.pop(rng.randrange(40))
        except Exception as exc:  # noqa: BLE001 (an OrderedDict changed during iteration, ...)
            errors.append(exc)

    threads = [threading.Thread(target=work, args=(seed,)) for seed in range(8)]
    for thread in threads:
        thread.start()
    for thread in threads:
        thread.join()
    assert errors == []
    assert len(cache) <= 16 and len(set(cache.keys())) == len(cache)


def test_every_module_level_cache_of_the_package_is_one_cache_type():
    from appell.core import partition, simplification
    from appell.numerics import boundary, linearise
    from appell.numerics.codegen import build, model
    from appell.simulation.sweep import runs

    caches = [
        boundary._models,
        linearise._COMPILED,
        model._STARTED,
        build._LOADED,
        runs._MODELS,
        simplification._TIDIED,
        simplification._READABLE,
        partition._JACOBIANS,
    ]
    assert all(isinstance(c, Cache) for c in caches)
    assert [c.identity for c in caches[:3]] == [True, True, True]  # per derivation


def test_no_other_kind_of_cache_is_left_in_the_package():
    """No functools cache, OrderedDict or weak table beside appell._cache; the viewer's
    scripts are read once (one value, no key: not a cache per derivation or per key)."""
    import re
    from pathlib import Path

    import appell

    allowed = {"_cache.py": ("OrderedDict",), "page.py": ("lru_cache", r"@cache\b")}  # @cache: ruff UP033
    found = []
    for path in sorted(Path(appell.__file__).parent.rglob("*.py")):
        text = path.read_text(encoding="utf-8")
        for kind in (
            "lru_cache",
            r"functools\.cache\b",
            r"@cache\b",
            "OrderedDict",
            "WeakKeyDictionary",
            "WeakValueDictionary",
        ):
            if re.search(kind, text) and kind not in allowed.get(path.name, ()):
                found.append(f"{path.name}: {kind}")
    assert found == []


def test_threads_that_miss_at_once_all_get_the_first_value_kept():
    """Eight threads miss the same key together (a barrier inside ``make``), each makes its own
    value; every one of them gets the one value that was kept, as a compiled model built twice
    must still be one model in use."""
    cache = Cache(4, identity=True)
    key = object()
    barrier = threading.Barrier(8)
    got = [None] * 8

    def work(i):
        def make():
            barrier.wait(timeout=10)
            return [i]  # a distinct object per thread

        got[i] = cache.get_or_make(key, make)

    threads = [threading.Thread(target=work, args=(i,)) for i in range(8)]
    for thread in threads:
        thread.start()
    for thread in threads:
        thread.join()
    assert all(g is got[0] for g in got) and cache.get(key) is got[0]

"""psbench's memory policies (numpy's huge-page advice off, glibc keeping freed memory)
hold during a heavy call, are restored after it, and the user's environment wins."""
import importlib
import threading

import numpy as np
import pytest

import psbench as ps
from psbench._shared import memory

SWITCH = memory._switch()
pytestmark = pytest.mark.skipif(SWITCH is None, reason="this numpy has no huge-page switch")


def advice():
    """numpy's current setting, read without changing it."""
    prev = SWITCH(True)
    SWITCH(prev)
    return prev


@pytest.fixture
def advice_on():
    prev = SWITCH(True)
    yield
    SWITCH(prev)


@pytest.mark.skipif(memory._SET is None, reason="NUMPY_MADVISE_HUGEPAGE is set here")
def test_off_inside_restored_after(advice_on):
    seen = []
    inner = memory.managed_memory(lambda: seen.append(advice()))
    outer = memory.managed_memory(lambda: (seen.append(advice()), inner(), seen.append(advice())))
    outer()
    assert seen == [False, False, False]   # nested: still off after the inner call returns
    assert advice() is True


@pytest.mark.skipif(memory._SET is None, reason="NUMPY_MADVISE_HUGEPAGE is set here")
def test_restored_after_an_error(advice_on):
    def boom():
        assert advice() is False
        raise ValueError("x")
    with pytest.raises(ValueError):
        memory.managed_memory(boom)()
    assert advice() is True


@pytest.mark.skipif(memory._SET is None, reason="NUMPY_MADVISE_HUGEPAGE is set here")
def test_concurrent_calls_keep_it_off_until_the_last(advice_on):
    entered, release, seen = threading.Event(), threading.Event(), []

    def slow():
        entered.set()
        release.wait(10)

    t = threading.Thread(target=memory.managed_memory(slow))
    t.start()
    entered.wait(10)
    memory.managed_memory(lambda: None)()   # a second call ends while the first runs
    seen.append(advice())
    release.set()
    t.join(10)
    assert seen == [False] and advice() is True


@pytest.mark.skipif(memory._SET is None, reason="NUMPY_MADVISE_HUGEPAGE is set here")
def test_solve_runs_with_plain_pages(advice_on, monkeypatch):
    from psbench.solve import _engine
    seen = []
    real = _engine.run

    def spy(*a, **k):
        seen.append(advice())
        return real(*a, **k)
    monkeypatch.setattr(_engine, "run", spy)
    s = ps.make_surface("semisphere", size=16)
    lay = ps.layout("45x8")
    ps.solve(ps.render(s, lay, model="lambert").images, lay)
    assert seen == [False] and advice() is True


def _reloaded(monkeypatch, **env):
    """The memory module as it reads this environment at import."""
    for k, v in env.items():
        monkeypatch.setenv(k, v)
    return importlib.reload(memory)


@pytest.fixture
def reload_after():
    yield
    importlib.reload(memory)


@pytest.mark.skipif(memory._SET is None, reason="NUMPY_MADVISE_HUGEPAGE is set here")
def test_the_users_environment_wins(monkeypatch, advice_on, reload_after):
    m = _reloaded(monkeypatch, NUMPY_MADVISE_HUGEPAGE="1")
    assert m._SET is None
    assert m.managed_memory(lambda: advice())() is True      # numpy's advice left alone
    m = _reloaded(monkeypatch, GLIBC_TUNABLES="glibc.malloc.mmap_max=0")
    assert m._LIBC is None                                      # malloc left alone
    f = lambda: None   # noqa: E731
    assert m.managed_memory(f) is f                             # both chosen: no wrapper
    monkeypatch.delenv("GLIBC_TUNABLES")
    m = _reloaded(monkeypatch, MALLOC_TRIM_THRESHOLD_="1000000")
    assert m._LIBC is None


class _FakeLibc:
    def __init__(self):
        self.calls = []

    def mallopt(self, param, value):
        self.calls.append((param, value))
        return 1


def test_malloc_keeps_freed_memory_during_the_outermost_call(monkeypatch):
    fake = _FakeLibc()
    monkeypatch.setattr(memory, "_LIBC", fake)
    seen = []
    inner = memory.managed_memory(lambda: seen.append(list(fake.calls)))
    memory.managed_memory(lambda: (inner(), seen.append(list(fake.calls))))()
    during = [(memory.M_MMAP_MAX, 0), (memory.M_TRIM_THRESHOLD, memory.KEEP_TRIM)]
    assert seen == [during, during]            # set once, on entering the outermost call
    assert fake.calls == during + list(memory.AFTER)   # and left as glibc's rule would


def test_malloc_restored_after_an_error(monkeypatch):
    fake = _FakeLibc()
    monkeypatch.setattr(memory, "_LIBC", fake)

    def boom():
        raise ValueError("x")
    with pytest.raises(ValueError):
        memory.managed_memory(boom)()
    assert fake.calls[-len(memory.AFTER):] == list(memory.AFTER)


@pytest.mark.skipif(memory._malloc() is None, reason="not glibc, or malloc tuned here")
def test_real_malloc_policy_keeps_values(reload_after):
    """On glibc the real mallopt calls succeed and the arrays are what they would be."""
    libc = memory._malloc()
    assert libc.mallopt(memory.M_MMAP_MAX, 65536) == 1
    f = memory.managed_memory(lambda: [np.full((3000, 3000), float(i)).sum() for i in range(3)])
    assert f() == [0.0, 9e6, 18e6]

"""numpy's huge-page advice is off while psbench solves, restored after, and the
user's NUMPY_MADVISE_HUGEPAGE wins."""
import importlib
import threading

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
    inner = memory.plain_pages(lambda: seen.append(advice()))
    outer = memory.plain_pages(lambda: (seen.append(advice()), inner(), seen.append(advice())))
    outer()
    assert seen == [False, False, False]   # nested: still off after the inner call returns
    assert advice() is True


@pytest.mark.skipif(memory._SET is None, reason="NUMPY_MADVISE_HUGEPAGE is set here")
def test_restored_after_an_error(advice_on):
    def boom():
        assert advice() is False
        raise ValueError("x")
    with pytest.raises(ValueError):
        memory.plain_pages(boom)()
    assert advice() is True


@pytest.mark.skipif(memory._SET is None, reason="NUMPY_MADVISE_HUGEPAGE is set here")
def test_concurrent_calls_keep_it_off_until_the_last(advice_on):
    entered, release, seen = threading.Event(), threading.Event(), []

    def slow():
        entered.set()
        release.wait(10)

    t = threading.Thread(target=memory.plain_pages(slow))
    t.start()
    entered.wait(10)
    memory.plain_pages(lambda: None)()   # a second call ends while the first runs
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


@pytest.mark.skipif(memory._SET is None, reason="NUMPY_MADVISE_HUGEPAGE is set here")
def test_the_users_environment_wins(monkeypatch, advice_on):
    monkeypatch.setenv("NUMPY_MADVISE_HUGEPAGE", "1")
    try:
        importlib.reload(memory)
        f = lambda: advice()   # noqa: E731
        assert memory.plain_pages(f) is f and f() is True
    finally:
        monkeypatch.delenv("NUMPY_MADVISE_HUGEPAGE")
        importlib.reload(memory)
    assert memory._SET is not None

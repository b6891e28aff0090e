"""How a run is timed: one pinned thread per library, and an untimed warm-up solve."""
from __future__ import annotations

import numpy as np

__all__ = ["pinned_threads", "warm_up", "WARM_UP_SIZE"]


class pinned_threads:
    """Run with one BLAS / OpenMP / numba thread: a run's numbers must not depend on how
    it was launched (a single ``psbench`` call, a ``-m`` worker, a shard job), and the
    thread count changes the summation order of multi-threaded BLAS kernels."""

    def __enter__(self):
        from threadpoolctl import threadpool_limits

        self._lim = threadpool_limits(limits=1)
        # numba's parallel kernels have their own pool (thread-local setting)
        import numba

        self._numba = numba.get_num_threads()
        numba.set_num_threads(1)
        return self

    def __exit__(self, *exc):
        import numba

        numba.set_num_threads(self._numba)
        self._lim.restore_original_limits()
        return False


#: side of the crop solved before a timed solve (see :func:`warm_up`)
WARM_UP_SIZE = 16


def warm_up(solve_run, p, sc):
    """Solve a small central crop of the scene exactly as run ``p`` will (``solve_run``),
    untimed, so that ``t_solve`` is the solve's own time: the first call of a compiled kernel in a
    process loads it (and numba's runtime), a one-time cost of 0.1-0.7 s that would
    otherwise land on whichever run of a chunk comes first. Failures and warnings here
    are ignored; the timed solve reports them."""
    import warnings

    k, H, W = sc.images.shape
    n = min(WARM_UP_SIZE, H, W)
    r0, c0 = (H - n) // 2, (W - n) // 2
    crop = (slice(r0, r0 + n), slice(c0, c0 + n))
    object_mask = (None if sc.object_mask is None
                   else np.ascontiguousarray(np.asarray(sc.object_mask)[crop]))
    images = np.ascontiguousarray(sc.images[(slice(None),) + crop])
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        try:
            solve_run(p, images, sc.lights, object_mask)
        except Exception:  # noqa: BLE001 - a warm-up only; the timed solve raises
            pass

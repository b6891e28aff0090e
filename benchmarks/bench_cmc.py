"""CMC per pair: median wall time of :func:`psbench.forensic.cmc` on two ~550^2 maps.

Baselines in the same run: the exhaustive search (``coarse=1``: every angle and
translation at full resolution, psbench's search before the coarse-to-fine one) and
:func:`psbench.forensic.compare` (band-pass and whole-map registration over the full
circle, CCFmax only). Inputs are the shared real scans when
present (``$PSBENCH_X3P``, default ../shared/data/forensic/weller, read with ``x3pio``),
else band-limited synthetic fields of the same size. The load average is printed: the
machine may be shared.

    .venv/bin/python benchmarks/bench_cmc.py [--repeat 5]
"""
import argparse
import os
import statistics
import time
import warnings

import cv2
import numpy as np

from psbench.forensic import cmc, compare


def _scans():
    folder = os.environ.get("PSBENCH_X3P", "../shared/data/forensic/weller")
    try:
        import x3pio
        out = []
        for name in ("TW01-01", "TW01-02", "TW02-01"):
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")
                z = np.asarray(x3pio.read(os.path.join(folder, name + ".x3p")).layers[0].z)
            z = (z * 1e6).astype(np.float32)
            out.append((name, z, np.isfinite(z)))
        return out, 6.25
    except (ImportError, OSError, ValueError):
        rng = np.random.default_rng(0)
        out = []
        for i in range(3):
            z = cv2.GaussianBlur(rng.standard_normal((556, 556)).astype(np.float32), (0, 0), 2)
            yy, xx = np.mgrid[:556, :556] - 277.5
            v = np.hypot(yy, xx) < 270
            out.append((f"synthetic{i}", z, v))
        return out, 6.25


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--repeat", type=int, default=5)
    args = ap.parse_args()
    scans, px = _scans()
    print(f"load average {os.getloadavg()}, inputs {[s[0] for s in scans]}")
    pairs = [(scans[0], scans[1], "same gun"), (scans[0], scans[2], "different guns")]
    for a, b, kind in pairs:
        cmc(a[1], b[1], a[2], b[2], pixel_size=px)      # warm-up
        t_cmc, t_full, t_reg = [], [], []
        for _ in range(args.repeat):
            t0 = time.perf_counter()
            r = cmc(a[1], b[1], a[2], b[2], pixel_size=px)
            t_cmc.append(time.perf_counter() - t0)
            t0 = time.perf_counter()
            f = cmc(a[1], b[1], a[2], b[2], pixel_size=px, coarse=1)
            t_full.append(time.perf_counter() - t0)
            t0 = time.perf_counter()
            m = compare(np.nan_to_num(a[1]), np.nan_to_num(b[1]), a[2], b[2], pixel_size=px)
            t_reg.append(time.perf_counter() - t0)
        mc, mf, mr = (statistics.median(t) for t in (t_cmc, t_full, t_reg))
        print(f"{a[0]} vs {b[0]} ({kind}, {a[1].shape} vs {b[1].shape}): cmc {mc:.3f} s "
              f"(count {r.count}/{len(r.cells)}, CCF {r.ccf:.3f}); exhaustive {mf:.3f} s "
              f"(count {f.count}, CCF {f.ccf:.3f}); compare {mr:.3f} s (CCFmax {m.ccf:.3f}); "
              f"cmc / exhaustive {mc / mf:.2f}, cmc / compare {mc / mr:.2f}")
    print(f"load average {os.getloadavg()}")


if __name__ == "__main__":
    main()

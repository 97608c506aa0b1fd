"""The reference timings of results/BENCHMARKS.md: the same work as magstand's fits, in
pandas + numpy and in PySINDy, on the bench's 1,000,000-row recording.

    python3 results/reference_fits.py million.csv

Prints seconds end to end (read the CSV, build the input, fit) for:
- pandas + numpy: the paper's fit (3 local models at 0, 0.5, 1, width 4, local weighted least
  squares per model and axis) on the overall throttle, the eq. 9 reference from the
  motors-off rows;
- PySINDy: a generic degree-5 polynomial of the throttle per axis (PolynomialLibrary + STLSQ
  without thresholding), the comparison the issue was filed with.
"""
import sys
import time

import numpy as np
import pandas as pd


def paper_fit(path):
    t = time.perf_counter()
    d = pd.read_csv(path)
    thr = d[[c for c in d.columns if c.startswith("thr_")]].to_numpy()
    u = thr.mean(axis=1)
    mag = d[["mag_x_ut", "mag_y_ut", "mag_z_ut"]].to_numpy()
    off = (thr == 0).all(axis=1)
    y = mag - mag[off].mean(axis=0)
    centers, eps = np.array([0.0, 0.5, 1.0]), 4.0
    e = np.exp(-((eps * (u[:, None] - centers[None, :])) ** 2))
    phi = e / e.sum(axis=1, keepdims=True)
    x = np.stack([u, np.ones_like(u)], axis=1)
    coef = []
    for i in range(3):
        w = phi[:, i]
        xtx = x.T @ (x * w[:, None])
        xty = x.T @ (y * w[:, None])
        coef.append(np.linalg.solve(xtx, xty))
    return time.perf_counter() - t, coef


def sindy_fit(path):
    import pysindy as ps

    t = time.perf_counter()
    d = pd.read_csv(path)
    thr = d[[c for c in d.columns if c.startswith("thr_")]].to_numpy()
    u = thr.mean(axis=1)[:, None]
    mag = d[["mag_x_ut", "mag_y_ut", "mag_z_ut"]].to_numpy()
    lib = ps.PolynomialLibrary(degree=5)
    theta = lib.fit_transform(u)
    opt = ps.STLSQ(threshold=0.0)
    opt.fit(np.asarray(theta), mag)
    return time.perf_counter() - t, opt.coef_


if __name__ == "__main__":
    path = sys.argv[1]
    for name, f in [("pandas+numpy paper fit", paper_fit), ("PySINDy degree-5 polynomial", sindy_fit)]:
        times = [f(path)[0] for _ in range(3)]
        print(f"{name}: {min(times):.2f} to {max(times):.2f} s over 3 runs")

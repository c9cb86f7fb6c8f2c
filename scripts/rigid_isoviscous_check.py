#!/usr/bin/python3
"""Independent check of ehlsim's rigid isoviscous rolling contact (body.elastic = false, L = 0).

In units where H0 = 1 (X, Y in H0^(1/2), P in lambda_bar H0^(-3/2)) the problem has no
parameter: div(H^3 grad P) = dH/dX, H = 1 + X^2/2 + Y^2/2, P = 0 on the edges, P >= 0 (the
complementarity form of cavitation), solved here by projected SOR.  With F = Int Int P the
load 2 pi / 3 gives H0 = (3 lambda_bar F / (2 pi))^2 and Hc_Moes M^2 = 36 F^2 for any M.

    /usr/bin/python3 scripts/rigid_isoviscous_check.py MESH X_MIN X_MAX Y_HALF
    e.g. 0.2 -21.3 7.1 14.2   (the default domain of M = 10 in units of H0^(1/2))
"""
import sys

import numpy as np


def solve(h, x0, x1, yw, omega=1.9, tol=1e-10, maxit=200000):
    x = np.arange(x0, x1 + h / 2, h)
    y = np.arange(-yw, yw + h / 2, h)
    X, Y = np.meshgrid(x, y, indexing="ij")
    e = (1 + X**2 / 2 + Y**2 / 2) ** 3
    ee = 0.5 * (e[1:-1, 1:-1] + e[2:, 1:-1])
    ew = 0.5 * (e[1:-1, 1:-1] + e[:-2, 1:-1])
    en = 0.5 * (e[1:-1, 1:-1] + e[1:-1, 2:])
    es = 0.5 * (e[1:-1, 1:-1] + e[1:-1, :-2])
    diag = ee + ew + en + es
    rhs = h * h * X[1:-1, 1:-1]  # dH/dX = X
    P = np.zeros_like(X)
    I, J = np.meshgrid(np.arange(1, len(x) - 1), np.arange(1, len(y) - 1), indexing="ij")
    colours = [(I + J) % 2 == c for c in (0, 1)]
    for it in range(maxit):
        change = 0.0
        for m in colours:
            gs = (ee * P[2:, 1:-1] + ew * P[:-2, 1:-1] + en * P[1:-1, 2:] + es * P[1:-1, :-2]
                  - rhs) / diag
            inner = P[1:-1, 1:-1]
            new = np.maximum(0.0, inner + omega * (gs - inner))
            change = max(change, np.abs(new - inner)[m].max())
            inner[m] = new[m]
        if change < tol:
            break
    return P.sum() * h * h, it


if __name__ == "__main__":
    h, x0, x1, yw = (float(a) for a in sys.argv[1:5])
    F, it = solve(h, x0, x1, yw)
    print(f"mesh {h} on [{x0}, {x1}] x [-{yw}, {yw}]: F = {F:.6f}, "
          f"Hc_Moes M^2 = 36 F^2 = {36 * F * F:.4f} ({it} sweeps)")

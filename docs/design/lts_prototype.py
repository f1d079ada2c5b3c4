#!/usr/bin/env python3
"""Local time stepping on a leaf-only two-level grid: a 1D prototype of the scheme proposed in
local-time-stepping.md (not used by grainwave; it checks the scheme's order before the solver
gets it).

u_t + u_x = 0 on [0, 1) periodic; fine points (spacing h) on [0.25, 0.75), coarse points (2h)
elsewhere; 4th-order central differences; classical RK4. Ghosts as in the wavelet grid: a fine
ghost on a coarse point takes its value, one between coarse points the 4-point Deslauriers-Dubuc
midpoint value; a coarse ghost inside the fine region takes the fine value there (injection).

  global  both levels step with the fine dt; ghosts exchanged at every stage.
  lts     the coarse level takes one step of 2 dt over its points plus a halo of injected fine
          values 10 coarse points wide (its own points then see exact RK4 stages); the fine level
          takes two steps of dt, its coarse ghosts from the coarse step's dense output (the
          3rd-order continuous extension of RK4), formed per stage as the interior's stages are
          (start value + a dt times the rate at the previous stage's time; Carpenter, Gottlieb,
          Abarbanel & Don, SIAM J. Sci. Comput. 16, 1995), or with --naive at the stage times.

usage: docs/design/lts_prototype.py [--naive] [--cfl=C]      (prints Linf errors and orders)
"""
import sys

import numpy as np

NAIVE = "--naive" in sys.argv
CFL = float(next((a.split("=", 1)[1] for a in sys.argv if a.startswith("--cfl=")), 0.8))
HALO = 10  # coarse points: 4 stages x stencil reach 2, plus the last stage's reach


def derivative(u, dx):
    """4th-order central first derivative at u[2:-2]."""
    return (-u[4:] + 8 * u[3:-1] - 8 * u[1:-3] + u[:-4]) / (12 * dx)


def midpoint(a, b, c, d):
    """Deslauriers-Dubuc (4-point) value halfway between b and c."""
    return (-a + 9 * b + 9 * c - d) / 16


def exact(x, t, kind):
    y = (x - t) % 1.0
    return np.sin(2 * np.pi * y) if kind == "sin" else np.exp(-((y - 0.5) / 0.08) ** 2)


def run(n, scheme, kind, t_end=1.0):
    h, big_h = 1.0 / n, 2.0 / n
    xf = np.arange(n // 4, 3 * n // 4) * h  # fine: [0.25, 0.75)
    xc = np.concatenate([np.arange(3 * n // 8, n // 2) * big_h - 1.0, np.arange(0, n // 8) * big_h])  # [-0.25, 0.25)
    uf, uc = exact(xf, 0, kind), exact(xc, 0, kind)
    nc = len(uc)
    steps = int(round(t_end / (2 * CFL * h)))
    dt = t_end / (2 * steps)

    def fine_ghosted(f, c):
        # Left of 0.25: 0.25 - 2h is the last coarse point, 0.25 - h a midpoint. Right of 0.75
        # (= -0.25): 0.75 is the first coarse point, 0.75 + h a midpoint.
        left = [c[nc - 1], midpoint(c[nc - 2], c[nc - 1], f[0], f[2])]
        right = [c[0], midpoint(f[-2], c[0], c[1], c[2])]
        return np.concatenate([left, f, right])

    def coarse_with(c, f, width):
        even = f[0::2]  # the fine values on coarse points
        return np.concatenate([even[len(even) - width:], c, even[:width]])

    def rk4(u, rate, step):
        k1 = rate(u, 0, [])
        k2 = rate(u + step / 2 * k1, 1, [k1])
        k3 = rate(u + step / 2 * k2, 2, [k1, k2])
        k4 = rate(u + step * k3, 3, [k1, k2, k3])
        return u + step / 6 * (k1 + 2 * k2 + 2 * k3 + k4)

    work = 0
    if scheme == "global":
        for _ in range(2 * steps):
            both = np.concatenate([uf, uc])

            def rate(y, stage, ks):
                nonlocal work
                f, c = y[:len(uf)], y[len(uf):]
                work += len(y)
                return np.concatenate([-derivative(fine_ghosted(f, c), h), -derivative(coarse_with(c, f, 2), big_h)])

            both = rk4(both, rate, dt)
            uf, uc = both[:len(uf)], both[len(uf):]
        return uf, uc, xf, xc, work

    for _ in range(steps):
        big_dt = 2 * dt
        ext = coarse_with(uc, uf, HALO)
        stages = []

        def coarse_rate(y, stage, ks):
            # Valid where the previous stage's rate was: the halo's edges lose 2 points a stage.
            nonlocal work
            s = 2 * stage
            r = np.zeros_like(y)
            r[s + 2:len(y) - s - 2] = -derivative(y[s:len(y) - s], big_h)
            work += len(y) - 2 * s - 4
            stages.append(r)
            return r

        new_ext = rk4(ext, coarse_rate, big_dt)
        k1, k2, k3, k4 = stages

        def dense(theta):  # RK4's continuous extension over the coarse step, and its rate
            b1, b23, b4 = theta - 1.5 * theta**2 + 2 / 3 * theta**3, theta**2 - 2 / 3 * theta**3, -0.5 * theta**2 + 2 / 3 * theta**3
            return ext + big_dt * (b1 * k1 + b23 * (k2 + k3) + b4 * k4)

        def dense_rate(theta):
            return (1 - 3 * theta + 2 * theta**2) * k1 + (2 * theta - 2 * theta**2) * (k2 + k3) + (-theta + 2 * theta**2) * k4

        for sub in range(2):
            start = sub * dt / big_dt
            start_value = dense(start)

            def fine_rate(y, stage, ks):
                nonlocal work
                a = (0, 0.5, 0.5, 1.0)[stage]
                if NAIVE:
                    ghosts = dense(start + a * dt / big_dt)
                elif stage == 0:
                    ghosts = start_value
                else:  # formed as the interior's stage: start + a dt * rate at the previous stage's time
                    ghosts = start_value + a * dt * dense_rate(start + (0, 0, 0.5, 0.5)[stage] * dt / big_dt)
                work += len(y)
                return -derivative(fine_ghosted(y, ghosts[HALO:HALO + nc]), h)

            uf = rk4(uf, fine_rate, dt)
        uc = new_ext[HALO:HALO + nc]
    return uf, uc, xf, xc, work


def main():
    print(f"CFL {CFL} (of the fine spacing), ghosts {'at the stage times' if NAIVE else 'formed per stage'}")
    for kind in ("gauss", "sin"):
        previous = {}
        for n in (256, 512, 1024, 2048):
            line = f"{kind:5s} n={n:5d}"
            for scheme in ("global", "lts"):
                uf, uc, xf, xc, work = run(n, scheme, kind)
                err = max(np.max(np.abs(uf - exact(xf, 1.0, kind))), np.max(np.abs(uc - exact(xc, 1.0, kind))))
                order = np.log2(previous[scheme] / err) if scheme in previous else float("nan")
                previous[scheme] = err
                line += f" | {scheme}: Linf {err:.3e} order {order:5.2f} point-RHS {work:.3e}"
            print(line)


if __name__ == "__main__":
    main()

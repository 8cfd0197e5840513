"""Cost of the contour-error search: global (project_point) against warm-started (project_point_warm).

Run: ``python benchmarks/projector_cost.py`` (``--repeats N``, ``--seed S``).

The trajectories are the env's reference paths (heart and omega, 100 mm/s,
0.12 s ramps, dt = 0.1 ms, as ``VCNC-*-v0``) offset by a random-walk error:

* ``near``: the whole path, error 0-20 um (a 2-D random walk, 1 um steps,
  kept inside a 20 um disk), the regime of a controller that follows;
* ``far``: 1-3 mm error (the walk's radius kept in [1, 3] mm, its direction
  turning slowly), the regime of a diverging episode;
* ``corners``: both errors on the stretches within 3 mm of path of the
  omega's four sharpest corners (radii of curvature 0.19 mm and 0.77 mm:
  1-3 mm inside them is past the centre of curvature, where feet lie on
  both sides).

Both kernels run over the same points in one compiled loop each
(:meth:`ContourProjector.project` and :meth:`ContourProjector.track`: one
query per control period, the warm one carrying its foot from point to
point).  Printed: the best of ``--repeats`` runs in ns of the thread's CPU
time per query (``time.thread_time``, so other processes on a shared
machine do not inflate it), and the largest distance difference between the
two (they must agree to rounding).
"""

from __future__ import annotations

import argparse
import time

import numpy as np

from vcnc_gym.contour import ContourProjector
from vcnc_gym.geometry import heart, omega
from vcnc_gym.motion import SCurveFeedrate, interpolate

SHAPES = {"heart": heart, "omega": omega}


def random_walk(rng, k: int, r_min: float, r_max: float, step: float) -> np.ndarray:
    """(k, 2) offsets, mm: a 2-D random walk of `step` mm steps with its radius kept in [r_min, r_max]."""
    e = np.empty((k, 2))
    p = rng.normal(size=2)
    p *= 0.5 * (r_min + r_max) / np.linalg.norm(p)
    steps = rng.normal(0.0, step, (k, 2))
    for i in range(k):
        p = p + steps[i]
        r = np.linalg.norm(p)
        if r > r_max:
            p *= r_max / r
        elif 0.0 < r < r_min:
            p *= r_min / r
        e[i] = p
    return e


def corner_mask(curve, ref, count: int, arc: float) -> np.ndarray:
    """Reference samples within `arc` mm of path length of the `count` sharpest curvature peaks."""
    grid = np.linspace(*curve.u_range, 20001)
    d = curve.derivatives_array(grid, 2)
    kappa = np.abs(d[:, 1, 0] * d[:, 2, 1] - d[:, 1, 1] * d[:, 2, 0]) / np.linalg.norm(d[:, 1], axis=1) ** 3
    peaks = [i for i in range(1, len(grid) - 1) if kappa[i] >= kappa[i - 1] and kappa[i] >= kappa[i + 1]]
    peaks = sorted(peaks, key=lambda i: -kappa[i])[:count]
    s = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(ref.position, axis=0), axis=1))])
    mask = np.zeros(len(s), bool)
    for i in peaks:
        s_peak = s[np.searchsorted(ref.u, grid[i]).clip(0, len(s) - 1)]
        mask |= np.abs(s - s_peak) < arc
    return mask


def trajectories(seed: int):
    """[(label, projector, points)] for every case."""
    rng = np.random.default_rng(seed)
    out = []
    for name, make in SHAPES.items():
        curve = make()
        proj = ContourProjector(curve)
        ref = interpolate(curve, SCurveFeedrate(feedrate=100.0, ramp_time=0.12), 1e-4)
        path = ref.position
        out.append((f"{name} near (0-20 um)", proj, path + random_walk(rng, len(path), 0.0, 0.02, 0.001)))
        out.append((f"{name} far (1-3 mm)", proj, path + random_walk(rng, len(path), 1.0, 3.0, 0.01)))
        if name == "omega":
            corners = path[corner_mask(curve, ref, 4, 3.0)]
            out.append((f"{name} corners far (1-3 mm)", proj, corners + random_walk(rng, len(corners), 1.0, 3.0, 0.01)))
            out.append(
                (f"{name} corners near (0-20 um)", proj, corners + random_walk(rng, len(corners), 0.0, 0.02, 0.001))
            )
    return out


def time_run(proj, q, warm: bool, repeats: int):
    """(best ns per query, distances) of one batched run, global or warm."""
    run = proj.track if warm else proj.project
    run(q[:10])  # compile
    best = np.inf
    for _ in range(repeats):
        t0 = time.thread_time()
        dist, _u = run(q)
        best = min(best, time.thread_time() - t0)
    return 1e9 * best / len(q), dist


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=5, help="timing repeats, best kept (default 5)")
    parser.add_argument("--seed", type=int, default=0, help="seed of the random-walk errors (default 0)")
    args = parser.parse_args(argv)
    print(
        f"{'trajectory':30s} {'points':>7s} {'global ns':>10s} {'warm ns':>9s} {'ratio':>6s} "
        f"{'max |d_w - d_g| mm':>19s}"
    )
    for label, proj, q in trajectories(args.seed):
        q = np.ascontiguousarray(q)
        t_global, d_global = time_run(proj, q, False, args.repeats)
        t_warm, d_warm = time_run(proj, q, True, args.repeats)
        dev = np.abs(d_warm - d_global).max()
        print(f"{label:30s} {len(q):7d} {t_global:10.0f} {t_warm:9.0f} {t_global / t_warm:6.2f} {dev:19.2e}")


if __name__ == "__main__":
    main()

"""Per-machine commissioning on plants from an env's box: the identified first mode against the true one, the
chosen bandwidth as a fraction of the mode, and the margins (experiments/commissioning/README.md).

    python experiments/commissioning/commissioning_report.py VCNC-HeartShop-v1 --plants 20

The plants are those of ``vcnc-bench --plants N`` (:func:`vcnc_bench.robust.plant_set`: the nominal plant, then
N draws with ``--plant-seed``); the experiment reads only the observation (:mod:`vcnc_baselines.commissioning`)."""

from __future__ import annotations

import argparse
import time

import gymnasium as gym
import numpy as np

import vcnc_gym  # noqa: F401
from vcnc_baselines.commissioning.record import commission
from vcnc_bench.robust import plant_set


def main(argv=None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("env_id")
    parser.add_argument("--plants", type=int, default=20)
    parser.add_argument("--plant-seed", type=int, default=0)
    args = parser.parse_args(argv)
    task = gym.make(args.env_id).unwrapped.task
    plants = plant_set(task.plant, args.plants, seed=args.plant_seed, max_vertices=0).parameters
    t0 = time.perf_counter()
    records = commission(task, "machine", plants)
    wall = time.perf_counter() - t0
    names = task.plant.parameter_names
    rows = []
    bands = [a.band[1] for r in records for a in r.axes]  # the identification band's top per axis, Hz
    for p, r in zip(plants, records):
        for j, (a, d) in enumerate(zip(r.axes, r.designs)):
            f_true = p[j, names.index("mode_frequency")] if "mode_frequency" in names else 0.0
            z_true = p[j, names.index("mode_damping")] if "mode_damping" in names else 0.0
            rows.append(
                (
                    f_true,
                    a.mode_frequency,
                    z_true,
                    a.mode_damping,
                    d.bandwidth,
                    d.margins.crossover,
                    d.margins.gain_db,
                    d.margins.phase_deg,
                    d.margins.sensitivity_db,
                )
            )
    rows = np.array(rows)
    found = rows[:, 1] > 0
    f_err = np.abs(rows[found, 1] / rows[found, 0] - 1.0) * 100
    z_err = np.abs(rows[found, 3] / rows[found, 2] - 1.0) * 100
    frac = rows[found, 5] / (2 * np.pi * rows[found, 1])
    print(
        f"{args.env_id}: {len(plants)} plants (nominal + {args.plants}), {len(rows)} axes; identification "
        f"{wall:.1f} s in all ({wall / len(plants):.2f} s per machine, batched)"
    )
    print(f"  mode found on {found.sum()} of {len(rows)} axes")
    for label, v, unit in (
        ("mode frequency error", f_err, "%"),
        ("mode damping error", z_err, "%"),
        ("crossover / mode", frac, ""),
        ("bandwidth (pole)", rows[:, 4], "rad/s"),
        ("gain margin", rows[:, 6], "dB"),
        ("phase margin", rows[:, 7], "deg"),
        ("sensitivity peak", rows[:, 8], "dB"),
    ):
        if v.size:
            higher_is_worse = "error" in label or "mode" in label or "sensitivity" in label
            print(
                f"  {label}: median {np.median(v):.3g}, worst {np.max(v) if higher_is_worse else np.min(v):.3g}"
                f" (min {np.min(v):.3g}, max {np.max(v):.3g}) {unit}"
            )
    print(
        f"  nominal plant: mode {rows[0, 1]:.2f} Hz (true {rows[0, 0]:.2f}), zeta {rows[0, 3]:.4f} "
        f"(true {rows[0, 2]:.4f})"
        + ("" if rows[0, 1] > 0 else f"; no mode found (0): the band's top is {bands[0]:.1f} Hz")
    )


if __name__ == "__main__":
    main()

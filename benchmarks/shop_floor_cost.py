"""Step cost of each shop-floor effect (vcnc_gym.plants.shop_floor) against the plain kernel, as ratios.

Run: ``python benchmarks/shop_floor_cost.py`` (``--steps``, ``--envs``, ``--repeats``).

The heart of VCNC-Heart-v1 on Jahanpour et al.'s feed drives, ``--envs`` machines in one
:class:`~vcnc_gym.envs.task.ContouringBatch` stepped by the serial kernel
(``step_serial``: the single env's path, one thread), each env under a PD
tracking loop closed on its own observation (computed outside the timed
call), so every configuration follows the contour (plant substeps with
friction and backlash, the exact contour error; the largest contour error is
printed beside the cost).  Configurations: the plain plant (no wrapper), the
wrapper with every effect off, each effect alone at its default
(:data:`~vcnc_gym.plants.shop_floor.EFFECT_PARAMETERS`), and every effect
(VCNC-HeartShop-v1).  They are timed in interleaved rounds in the same
process; the best round of each is kept and divided by the plain kernel's.
Only the kernel call is timed (the env's Python ``step`` around it is the
same for every configuration), in CPU time of the calling thread
(``time.thread_time``: the serial kernel runs there), so that the time other
processes take the core from it is not counted.  Target: every ratio within 1.3.
"""

from __future__ import annotations

import argparse
import time

import numpy as np

#: Each effect alone: the settings over every effect off (shop_floor.OFF), the effect at its default.
EFFECTS = {
    "encoder quantisation": ("encoder_resolution",),
    "measurement noise": ("noise_std",),
    "command delay": ("command_delay",),
    "sensor delay": ("sensor_delay",),
    "structural mode": ("mode_frequency",),
    "cutting force": ("cutting_force", "cutting_ripple"),
    "Stribeck friction": ("stribeck_force",),
}


def settings_for(names) -> dict:
    """Every effect off but ``names``, at their defaults (sensor_delay, 0 by default, at 1 period)."""
    from vcnc_gym.plants import shop_floor as sf

    settings = dict(sf.OFF)
    for name in names:
        settings[name] = 1.0 if name == "sensor_delay" else sf.EFFECT_PARAMETERS[sf.EFFECT_NAMES.index(name)].nominal[0]
    return settings


def make_batch(shop_floor, n_envs: int):
    from vcnc_gym.envs.task import ContouringBatch, ContouringTask

    task = ContouringTask(contour="heart", plant="vcnc_feed_drive", shop_floor=shop_floor)
    return ContouringBatch(task, n_envs)


def reset(batch) -> None:
    for i in range(batch.n_envs):
        batch.reset_env(i, batch.task.nominal_parameters, np.random.default_rng(i))
    batch.run()


def pd_command(layout, obs) -> np.ndarray:
    """Commands of a PD tracking loop (300 V/mm, 1 V s/mm, over u_max = 5 V) on observations (N, D) -> (N, 2)."""
    u = 300.0 * layout.tracking_error(obs) + 1.0 * (layout.reference_velocity(obs) - layout.velocity(obs))
    return np.clip(u / 5.0, -1.0, 1.0)


def time_batch(batch, n_steps: int) -> tuple[float, float]:
    """Seconds per env-step of the kernel over ``n_steps`` control periods of a PD loop closed on each env's
    observation (computed outside the timed call), and the largest contour error seen, mm."""
    from vcnc_gym.envs import step_kernel as sk

    reset(batch)
    b = batch.buffers
    layout = batch.task.layout
    total = 0.0
    peak = 0.0
    for _ in range(n_steps):
        b.action[:] = pd_command(layout, b.obs)
        b.mode[:] = sk.MODE_STEP
        t0 = time.thread_time()
        batch.run()
        total += time.thread_time() - t0
        peak = max(peak, float(b.info[:, sk.INFO_CONTOUR_ERROR].max()))
    return total / (n_steps * batch.n_envs), peak


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument(
        "--steps", type=int, default=1000, help="control periods per round (default 1000, 0.1 s of the heart's 3.2 s)"
    )
    parser.add_argument("--envs", type=int, default=16, help="machines in the batch (default 16)")
    parser.add_argument(
        "--repeats",
        type=int,
        default=30,
        help="interleaved rounds, best kept (default 30: short "
        "rounds, many of them, so that the best of each escapes other processes' load)",
    )
    args = parser.parse_args(argv)

    from tqdm import tqdm

    configs = {"plain kernel (VCNC-Heart-v1)": None, "wrapper, every effect off": settings_for(())}
    configs.update({name: settings_for(names) for name, names in EFFECTS.items()})
    # the mode changes the path (the table rings: a larger contour error, a longer closest-point search); at
    # 5 kHz, critically damped, it computes the same but leaves the path as it is: its own cost
    stiff = {"mode_frequency": 5000.0, "mode_damping": 1.0}
    configs["structural mode, 5 kHz (same path)"] = {**settings_for(("mode_frequency",)), **stiff}
    configs["every effect (VCNC-HeartShop-v1)"] = True
    configs["every effect, mode at 5 kHz"] = stiff
    batches = {name: make_batch(s, args.envs) for name, s in tqdm(configs.items(), desc="compiling")}
    best = {name: np.inf for name in configs}
    peaks = {}
    for _ in tqdm(range(args.repeats), desc="rounds"):
        for name, batch in batches.items():
            cost, peaks[name] = time_batch(batch, args.steps)
            best[name] = min(best[name], cost)
    plain = best["plain kernel (VCNC-Heart-v1)"]
    print(f"{'configuration':<36} {'us/env-step':>12} {'x plain':>8} {'max error um':>13}")
    for name, cost in best.items():
        print(f"{name:<36} {cost * 1e6:12.3f} {cost / plain:8.3f} {peaks[name] * 1e3:13.2f}")
    print(
        f"(serial kernel, {args.envs} envs x {args.steps} control periods of 0.1 ms, best of {args.repeats} "
        f"interleaved rounds)"
    )


if __name__ == "__main__":
    main()

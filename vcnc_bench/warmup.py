"""Compile the main job's controller kernels ahead of it: ``python -m vcnc_bench.warmup``.

:mod:`vcnc_gym.warmup` compiles the envs' kernels at install.  The default table (:data:`vcnc_bench.recipes.DEFAULT_IDS`)
also runs the controllers' compiled laws (one numba entry point per controller type,
:mod:`vcnc_gym.envs.controller_contract`): about 30 s of a core on a cold cache, paid inside the first run of
``vcnc-bench`` before this module existed, twice where two workers started on the same laws.  The install
(``make bench``'s set-up) runs this module once after the env warm-up, so that the benchmark step starts warm.

For one env of each machine of the default table (its first id per plant, ideal or shop floor) it builds every
classical policy the bench runs there (the ``baseline`` kind's defaults), resets the env, lets a floor plan (a
stored solution is loaded, not replayed: the bench's episode checks it) and makes one decision step: nothing is
measured, only compiled.  One fresh process per env, ``--jobs`` at a time (numba's cache is shared on disk: a
kernel one process compiled is loaded by the others).
"""

from __future__ import annotations

import argparse
import os
import sys

from vcnc_gym.warmup import warm_in_processes

__all__ = ["warm_env", "main"]

_ONE = "from vcnc_bench.warmup import warm_env; warm_env({id!r})"


def warm_env(env_id: str) -> int:
    """Build ``env_id`` and each classical policy the bench runs on it by default, reset, plan (a floor) and step
    once with each; the number of policies warmed."""
    import gymnasium as gym
    import numpy as np

    import vcnc_gym  # noqa: F401  (registers the ids)

    from .policies import policy_kinds, resolve_policy

    env = gym.make(env_id)
    kind = policy_kinds().get("baseline")
    specs = kind.defaults(env) if kind is not None else []
    warmed = 0
    for spec in specs:
        policy = resolve_policy(spec, env)
        if getattr(policy, "learns_across_episodes", False):
            continue  # not in the default table
        obs, _ = env.reset(seed=0)
        if hasattr(policy, "plan"):
            policy.plan(env)
        action, _ = policy.predict(obs, state=None, episode_start=np.array([True]), deterministic=True)
        env.step(action)
        warmed += 1
    env.close()
    return warmed


def _one_per_machine(ids: list[str]) -> list[str]:
    """The first of ``ids`` per machine (its plant's name, ideal or on the shop floor), in order."""
    from vcnc_gym.envs.registry import suite_env

    seen, out = set(), []
    for env_id in ids:
        kwargs = suite_env(env_id).kwargs
        machine = (kwargs.get("plant"), bool(kwargs.get("shop_floor")))
        if machine not in seen:
            seen.add(machine)
            out.append(env_id)
    return out


def main(argv=None) -> int:
    from .cli import DEFAULT_IDS, LONGEST_FIRST

    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--jobs", type=int, default=os.cpu_count() or 1, help="processes at a time (default: the cores)")
    args = p.parse_args(argv)
    if args.jobs < 1:
        p.error(f"--jobs must be >= 1, got {args.jobs}")
    ids = _one_per_machine(
        sorted(DEFAULT_IDS, key=lambda i: LONGEST_FIRST.index(i) if i in LONGEST_FIRST else len(LONGEST_FIRST))
    )
    # the ideal heart compiles the laws every machine shares; beside it the step response, whose plant has laws of
    # its own, rather than another machine that would compile the same laws at the same time
    rank = {ids[0]: 0, "VCNC-Step-v0": 1}
    ids.sort(key=lambda i: rank.get(i, 2))
    print(
        f"vcnc_bench.warmup: compiling the controllers' kernels on {len(ids)} envs, one per machine of the default "
        f"table, {args.jobs} at a time",
        flush=True,
    )
    return warm_in_processes("vcnc_bench.warmup", ids, _ONE, args.jobs)


if __name__ == "__main__":
    sys.exit(main())

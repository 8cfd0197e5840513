"""A torch forward pass beside the vector env's parallel kernel, per numba threading layer, in one run (issue 21).

Run: ``python benchmarks/numba_torch_threads.py`` (``--envs N``, ``--calls K``).

Training and agent evaluation run torch (the policy) and numba (the vector
env) in one process.  For each threading layer (GNU OpenMP, numba's default
on this machine, and numba's workqueue) a child process times the policy's
forward pass (SB3's MlpPolicy network, 64x64 for actor and critic, on N
observations of ``VCNC-Heart-v1``, one torch thread) before any parallel
kernel ran and then right after each of K calls of the vector env's
parallel kernel (``parallel=True``, 2 numba threads), and the kernel calls
themselves, then 50 forward passes in a row after the calls (as the
update of a rollout follows it).  It prints the times and the ratios to
the forward pass before any kernel ran.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys

_CHILD = r"""
import json, sys, time
import torch
torch.set_num_threads(1)
import gymnasium as gym, numba, numpy as np
from stable_baselines3.common.policies import ActorCriticPolicy
import vcnc_gym
n, calls = int(sys.argv[1]), int(sys.argv[2])
envs = gym.make_vec("VCNC-Heart-v1", num_envs=n, vectorization_mode="vector_entry_point", parallel=True)
space = envs.unwrapped.single_observation_space
policy = ActorCriticPolicy(space, envs.unwrapped.single_action_space, lambda _: 3e-4,
                           net_arch=dict(pi=[64, 64], vf=[64, 64]))
x = torch.randn(n, space.shape[0])
def forward(repeats):
    with torch.no_grad():
        t0 = time.perf_counter()
        for _ in range(repeats):
            a, b = policy.mlp_extractor(x); policy.action_net(a); policy.value_net(b)
        return (time.perf_counter() - t0) / repeats
forward(20)
before = forward(100)
obs, _ = envs.reset(seed=0)
a = np.zeros((n, 2), dtype=np.float32)
envs.step(a)
after, kernel = [], []
for _ in range(calls):
    t0 = time.perf_counter(); envs.step(a); kernel.append(time.perf_counter() - t0)
    after.append(forward(1))
block = forward(50)
print(json.dumps({"layer": numba.threading_layer(), "before_ms": 1e3 * before,
                  "after_ms": 1e3 * float(np.median(after)), "block_ms": 1e3 * block,
                  "kernel_ms": 1e3 * float(np.median(kernel))}))
"""


def main(argv=None) -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--envs", type=int, default=256, help="envs, and observations per forward pass (default 256)")
    p.add_argument("--calls", type=int, default=200, help="kernel calls, each followed by a forward pass")
    args = p.parse_args(argv)
    print(
        f"VCNC-Heart-v1, N = {args.envs}, 2 numba threads (parallel=True), 1 torch thread; medians over "
        f"{args.calls} kernel calls"
    )
    print(
        f"{'threading layer':16s} {'forward alone':>14s} {'after a kernel':>15s} {'ratio':>6s} "
        f"{'50 after the calls':>19s} {'ratio':>6s} {'kernel call':>12s}"
    )
    for layer in ("omp", "workqueue"):
        env = dict(os.environ, NUMBA_THREADING_LAYER=layer, NUMBA_NUM_THREADS="2")
        out = subprocess.run(
            [sys.executable, "-c", _CHILD, str(args.envs), str(args.calls)],
            env=env,
            capture_output=True,
            text=True,
            check=True,
        ).stdout
        r = json.loads(out.strip().splitlines()[-1])
        print(
            f"{r['layer']:16s} {r['before_ms']:11.3f} ms {r['after_ms']:12.3f} ms {r['after_ms'] / r['before_ms']:6.1f} "
            f"{r['block_ms']:16.3f} ms {r['block_ms'] / r['before_ms']:6.1f} {r['kernel_ms']:9.3f} ms",
            flush=True,
        )


if __name__ == "__main__":
    main()

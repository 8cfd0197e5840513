"""The identification experiment's holding loop in one kernel call (``Machines.hold``,
:func:`vcnc_gym.envs.step_kernel.run_holding_loop`) gives, to the bit, what the loop written in numpy
(``benchmarks/identification_loop.py``, the experiment's loop before the kernel) gives when it commands the machines
one period at a time (``Machines.step``): the experiment's record, and so every
commissioning, does not depend on which of the two ran it."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest
from benchmark_script import benchmark_script

import vcnc_gym  # noqa: F401
from vcnc_baselines.commissioning.identify import Machines


def _bench():
    """``benchmarks/identification_loop.py``: the numpy loop and the random loop arrays."""
    return benchmark_script("identification_loop")


@pytest.mark.parametrize(
    "env_id",
    ["VCNC-HeartShop-v1", "VCNC-Heart-v1", "VCNC-Circle-v1", "VCNC-CircleShop-v1", "VCNC-CornersSmoothShop-v1"],
)
def test_the_kernel_loop_is_the_numpy_loop_to_the_bit(env_id):
    bench = _bench()
    task = gym.make(env_id).unwrapped.task
    params = bench.box_plants(env_id, 3)
    assert not np.array_equal(params[0], params[1])
    a, b = Machines(task, params, seed=11), Machines(task, params, seed=11)
    h = bench.random_loop(np.random.default_rng(1), 3, 1500, a.u_max)
    ref = h._replace(u=np.zeros_like(h.u), e=np.zeros_like(h.e), velocity=np.zeros_like(h.velocity))
    a.hold(h)
    bench.numpy_loop(b, ref)
    assert np.all(np.isfinite(h.u)) and np.any(np.abs(h.e) > 0)
    for name in ("u", "e", "velocity"):
        np.testing.assert_array_equal(getattr(h, name), getattr(ref, name), err_msg=name)
    np.testing.assert_array_equal(a.observe(), b.observe())


def test_a_loop_for_other_machines_is_refused():
    task = gym.make("VCNC-Heart-v1").unwrapped.task
    machines = Machines(task, np.asarray(task.nominal_parameters)[None].repeat(2, axis=0))
    bench = _bench()
    with pytest.raises(ValueError, match="loop.u must be .2 machines"):
        machines.hold(bench.random_loop(np.random.default_rng(0), 3, 10, machines.u_max))
    loop = bench.random_loop(np.random.default_rng(0), 2, 10, machines.u_max)
    with pytest.raises(ValueError, match="loop.offset must be .10 periods"):
        machines.hold(loop._replace(offset=loop.offset[:5]))

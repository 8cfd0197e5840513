"""Shared test fixtures and the ``slow`` marker.

``slow`` marks a test that takes more than about 10 s on the 2-core CI machine.
``make test`` (CI) runs every test but the slow ones (``pytest -m "not slow"``), which keeps the CI run well
under 15 minutes; ``make test-all`` runs them too.
"""

from __future__ import annotations

import numpy as np
import pytest

#: The PD tracking loop the tests use as a plain, hand-written controller:
#: 300 V/mm on the tracking error and 1 V s/mm on the velocity error, the
#: action being the voltage over the 5 V limit of Jahanpour et al.'s drive.
PD_KP = 300.0  # V/mm
PD_KD = 1.0  # V s/mm
PD_LIMIT = 5.0  # V


def pytest_configure(config):
    config.addinivalue_line("markers", "slow: takes more than ~10 s on CI's 2 cores (deselect with -m 'not slow')")


def _pd_action(layout, obs, kp=PD_KP, kd=PD_KD):
    """The PD loop's normalised action for ``obs`` (one env or a batch), float32 like the observation."""
    u = kp * layout.tracking_error(obs) + kd * (layout.reference_velocity(obs) - layout.velocity(obs))
    return np.clip(u / PD_LIMIT, -1.0, 1.0).astype(np.float32)


def _pd_episode(env, kp=PD_KP, kd=PD_KD, seed=0):
    """Run the PD loop for one episode of ``env``; return (infos, terminated, truncated) of its last step."""
    layout = env.unwrapped.layout
    obs, _ = env.reset(seed=seed)
    infos = []
    while True:
        obs, _, term, trunc, info = env.step(_pd_action(layout, obs, kp, kd))
        infos.append(info)
        if term or trunc:
            return infos, term, trunc


@pytest.fixture
def pd_action():
    """``pd_action(layout, obs, kp=300, kd=1)``: the PD loop's action (V/mm, V s/mm, over 5 V)."""
    return _pd_action


@pytest.fixture
def pd_episode():
    """``pd_episode(env, kp=300, kd=1, seed=0)``: one PD episode, (infos, terminated, truncated)."""
    return _pd_episode


@pytest.fixture(scope="module")
def one_torch_thread():
    """Torch on one thread for a module (the agents' networks are tiny: one thread is several times faster than
    threads fighting over 2 cores); the previous count restored after it."""
    torch = pytest.importorskip("torch")
    n = torch.get_num_threads()
    torch.set_num_threads(1)
    yield
    torch.set_num_threads(n)

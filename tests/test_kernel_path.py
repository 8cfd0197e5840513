"""The vector env's choice of kernel path (serial or parallel): timed, cheaper path kept, results independent of it."""

from __future__ import annotations

import numpy as np
import pytest

from vcnc_gym.envs import ContouringVectorEnv
from vcnc_gym.envs import contouring_vector_env as cve


@pytest.fixture
def two_threads(monkeypatch):
    """KernelPath as on a 2-thread numba, whatever this machine's thread count."""
    monkeypatch.setattr(cve.numba, "get_num_threads", lambda: 2)


def _drive(path, seconds_of, calls, work=1000.0):
    """Run ``calls`` choices of ``path``, each timed by ``seconds_of(parallel, call)``; the paths chosen."""
    chosen = []
    for k in range(calls):
        parallel = path.choose(work)
        path.record(parallel, seconds_of(parallel, k))
        chosen.append(parallel)
    return np.array(chosen)


def test_the_first_call_of_each_path_is_not_timed_and_the_cheaper_path_is_kept(two_threads):
    path = cve.KernelPath()
    # compilation: the first call of each path takes 10 s, then serial 1 ms, parallel 0.5 ms a call
    chosen = _drive(path, lambda par, k: 10.0 if k in (0, 2) else (0.5e-3 if par else 1e-3), 200)
    assert list(chosen[:4]) == [False, False, True, True]  # serial twice, then parallel twice
    assert chosen[4:].mean() > 0.95  # parallel from then on, serial tried now and then
    assert path.cost == pytest.approx([1e-6, 0.5e-6])


def test_a_stalling_parallel_path_is_left_and_tried_at_most_two_percent_of_the_time(two_threads):
    path = cve.KernelPath()
    # a loaded core: parallel calls wait 5 ms for their thread, serial calls take 1 ms
    chosen = _drive(path, lambda par, k: 5e-3 if par else 1e-3, 3000)
    serial_time = np.sum(~chosen[10:]) * 1e-3
    parallel_time = np.sum(chosen[10:]) * 5e-3
    share = parallel_time / (serial_time + parallel_time)
    assert 0.5 / (cve.PROBE_RATIO + 1) < share < 1.1 / (cve.PROBE_RATIO + 1)


def test_the_parallel_path_is_taken_again_when_the_load_goes(two_threads):
    path = cve.KernelPath()
    loaded = 1000  # parallel stalls (5 ms) for the first 1000 calls, then takes 0.5 ms; serial 1 ms
    chosen = _drive(path, lambda par, k: (5e-3 if k < loaded else 0.5e-3) if par else 1e-3, 4000)
    assert chosen[loaded - 100 : loaded].mean() < 0.1
    # the first try after the change comes within PROBE_RATIO x (a loaded try) of serial calls, a second ~200 later
    assert chosen[loaded + 1300 :].mean() > 0.95, "back on the parallel path once it is cheaper (a try or two)"


def test_one_numba_thread_runs_the_serial_path_untimed(monkeypatch):
    monkeypatch.setattr(cve.numba, "get_num_threads", lambda: 1)
    path = cve.KernelPath()
    assert not _drive(path, lambda par, k: 1e-3, 10).any()
    assert path.cost == [None, None]


class _Alternating(cve.KernelPath):
    """Serial and parallel on alternate calls, whatever they cost."""

    def __init__(self):
        super().__init__()
        self.n = 0

    def choose(self, work):
        self.n += 1
        return self.n % 2 == 0


def test_results_do_not_depend_on_the_path():
    """Envs stepped by serial and parallel calls in turn give the forced-serial env's numbers to the bit."""
    n, steps = 20, 40
    kwargs = dict(contour="omega", randomize=True, max_episode_steps=15)
    runs = []
    for parallel in (False, None):
        envs = ContouringVectorEnv(n, parallel=parallel, **kwargs)
        if parallel is None:
            envs._path = _Alternating()
        obs, _ = envs.reset(seed=3)
        out = [obs]
        for t in range(steps):
            a = np.stack([np.sin(0.1 * t + np.arange(n)), np.cos(0.2 * t + np.arange(n))], axis=1)
            obs, r, te, tr, _ = envs.step(0.3 * a)
            out += [obs, r, te, tr]
        runs.append(out)
    assert envs._path.n >= steps
    for a, b in zip(*runs):
        np.testing.assert_array_equal(a, b)

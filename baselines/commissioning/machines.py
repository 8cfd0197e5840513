"""Commissioning each machine a controller runs on (the ``@machine`` variants), shared by every model-based law.

A controller built with ``commissioning="machine"`` starts from the nominal machine's record and, before an
episode, identifies each plant its env holds (:func:`machine_records`: one identification run over the machines never met
before), then rebuilds its law from those records: one design row per env.
:class:`PerMachine` is that bookkeeping, for the servo law's table (:class:`vcnc_baselines.servo.ServoPolicy`) and
the online feedforward (:class:`vcnc_baselines.feedforward.online.OnlineFeedforwardPIDPolicy`).
"""

from __future__ import annotations

import numpy as np

__all__ = ["PerMachine", "machine_records"]

#: The ``"machine"`` records of the machines this process met, by :func:`~.record.experiment_key` of the machine
#: alone: a controller that meets one plant at a time (the dial's search, one episode per plant and setting) meets
#: each again without another identification run.  :func:`~.record.commission` keeps its own by set of machines, the
#: last 8 sets; a machine's record is the same alone and in a batch (``tests/test_commissioning.py``).  The last
#: :data:`_KEPT` machines are kept.
_MET: dict = {}
_KEPT = 256


def machine_records(task, parameters) -> list:
    """The ``"machine"`` records of the machines ``parameters`` (n, 2, P) on ``task``: those met before from
    :data:`_MET`, the others from one :func:`~.record.commission` over them."""
    from .record import commission, experiment_key

    p = np.asarray(parameters, dtype=np.float64)
    keys = [experiment_key(task, q[None]) for q in p]
    missing = [i for i, k in enumerate(keys) if k not in _MET and keys.index(k) == i]
    if missing:
        for i, record in zip(missing, commission(task, "machine", p[missing])):
            if len(_MET) >= _KEPT:
                _MET.pop(next(iter(_MET)))
            _MET[keys[i]] = record
    return [_MET[k] for k in keys]


class PerMachine:
    """The per-machine commissioning of a controller (a mixin of :class:`~vcnc_baselines.base.BaselinePolicy`).

    The controller sets :attr:`commissioning` (``"machine"`` to commission each plant), :attr:`records` (one
    :class:`~vcnc_baselines.commissioning.record.CommissioningRecord`, or one per env), :attr:`task` (the env's
    task it was built from, or None), :attr:`dt` (the control period of its records, s), and implements ``_build``
    (the law from :attr:`records`) and ``_compiled_arrays``.
    """

    commissioning: str | None = None
    task = None
    #: The task whose reference the identification runs follow (:meth:`identify_on`); None: the env's own.
    identification_task = None
    #: The parameters (N, 2, P) the records were identified on, or None before the first commissioning.
    _commissioned_for = None
    #: Seconds of identification runs behind :attr:`records` (their sum).
    identification_s = 0.0

    def _commission_machines(self, env) -> bool:
        """With ``commissioning="machine"``: identify the plants ``env`` holds now that were not identified
        before (every plant of a new set; of the same N envs, those whose plant changed, such as the envs of a
        vector env that drew a new plant at their reset); True if the records changed."""
        if self.commissioning != "machine":
            return False
        u = getattr(env, "unwrapped", env)
        params = np.asarray(u.parameters, dtype=np.float64)
        params = params[None] if params.ndim == 2 else params
        done = self._commissioned_for
        if done is not None and done.shape == params.shape:
            changed = np.flatnonzero(np.any(done != params, axis=tuple(range(1, params.ndim))))
        else:
            changed = np.arange(params.shape[0])
        if changed.size == 0:
            return False
        task = self.identification_task or getattr(u, "task", None) or self.task
        if task is None:
            raise ValueError(
                f"baseline {self.name!r}: commissioning='machine' identifies each plant on a task's "
                f"reference, and {type(u).__name__} has no task (identify_on(task) names one)"
            )
        if task.dt != self.dt:
            raise ValueError(
                f"baseline {self.name!r}: commissioning='machine' designs the law for the control period "
                f"of the task it identifies on ({task.dt} s), and the law runs every {self.dt} s"
            )
        records = list(self.records) if changed.size < params.shape[0] else [None] * params.shape[0]
        for i, record in zip(changed, machine_records(task, params[changed])):
            records[i] = record
        self.records = records
        self.identification_s = float(sum(r.identification_s for r in records))
        self._commissioned_for = params.copy()
        return True

    def commission_again(self, env):
        """With ``commissioning="machine"``: commission the plants ``env``'s envs drew since the last call
        (:meth:`_commission_machines`) and rebuild the law; the compiled form around the current memory if the law
        changed (what a native vector env steps), else None.  What a trainer calls after a reset that draws plants
        (``randomize=True``): the law then fits every env's own machine."""
        if not self._commission_machines(env):
            return None
        self._build()
        return self._compiled_arrays()

    def identify_on(self, task) -> None:
        """With ``commissioning="machine"``: identify the machines while their axes follow ``task``'s reference
        (a :class:`~vcnc_gym.envs.task.ContouringTask` on the same plant and control period) instead of the env's.
        A CNC commissions a machine once, on one program, and runs every later program with that commissioning:
        the tolerance search (``experiments/tolerance/tolerance.py``) runs each look-ahead setting with the machines
        commissioned on the id's own reference, one identification run for every setting and controller."""
        if task.plant.name != self.plant.name or task.dt != self.dt:
            raise ValueError(
                f"identify_on: the task's plant and control period ({task.plant.name}, {task.dt} s) "
                f"must be the controller's ({self.plant.name}, {self.dt} s)"
            )
        self.identification_task = task
        self._commissioned_for = None

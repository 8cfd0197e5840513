"""The reference PD loop (``pd-ref``): the 0 of the normalised contour score, a fixed design, never tuned.

Per axis, a PD on the measured tracking error with no feedforward, no integral, no filter, no notch and no
commissioning run:

.. math::

    u_j = K_{p,j} (x_{d,j}[k] - x_j) + K_{d,j} (v_{d,j}[k] - v_j)

with the gains of :func:`vcnc_baselines.commissioning.design.pid_gains` ``(..., integral=False)``: pole placement of a
double closed-loop pole at ``w = FRACTION * servo_bandwidth`` on the *nominal, declared* axis ``m s^2 + c s``
(``m``, ``c`` from :meth:`vcnc_gym.plants.PlantModel.inverse` of the nominal parameters), so that

.. math::

    K_{p,j} = m_j w^2, \\qquad K_{d,j} = \\max(2 m_j w - c_j, 0).

This is the textbook position loop of a feed drive designed by pole placement on the rigid-body model
(Altintas, *Manufacturing Automation*, 2nd ed., 2012, the design of CNC feed drives; the suite's rule,
:func:`~vcnc_baselines.commissioning.design.pid_gains`, with the integral off), at a fixed fraction of the bandwidth the drive declares it supports: a deliberately plain
loop, the reference *weak* policy of the normalised score (:mod:`vcnc_bench.score`), as D4RL's random policy
(Fu et al., 2020) is theirs.  Its design is one formula of the nominal model; it is never re-tuned per id, so a
score of 0 means "as good as a PD loop commissioned by nobody".

It reads the reference at its own call count as the other servo controllers do (:mod:`vcnc_baselines.servo`: the
servo law with a table of zero feedforward and zero offsets, and no coupling), so it runs in the native vector
env and under ``--plants``.  The default ``vcnc-bench`` table runs it (a compiled law: well under a second an
episode), so that its JSON carries every policy's score (the leaderboard, :mod:`vcnc_bench.leaderboard`).
"""

from __future__ import annotations

import numpy as np

from ..commissioning.design import pid_gains
from ..servo import ServoGains, ServoPolicy, reference_table

__all__ = ["FRACTION", "ReferencePDPolicy"]

#: The reference PD's closed-loop double pole as a fraction of the plant's declared ``servo_bandwidth``
#: (:attr:`vcnc_gym.plants.PlantModel.servo_bandwidth`, rad/s): a fifth of the ceiling (200 rad/s on Jahanpour et
#: al.'s drive, 400 on Simba et al.'s, 6 on Purtojo et al.'s table).  Of 0.1, 0.15 and 0.2, the one at which the
#: loop completes every contouring id's nominal plant: at a tenth Purtojo et al.'s table on the shop floor lags
#: beyond the tracking bound (0.5 mm) on the circle, at 0.15 it does not finish it; at a fifth it completes there
#: (92 um max) and stays stable on the shop floor's drives, whose structural mode and delays it does not know of
#: (``tests/test_pd_ref.py``).
FRACTION = 0.2


class ReferencePDPolicy(ServoPolicy):
    """The reference PD loop of the normalised contour score (see the module docstring).

    Parameters
    ----------
    layout, decision_period, nominal_parameters, plant, reference, dt, task
        As :class:`~vcnc_baselines.servo.ServoPolicy` (:meth:`from_env` fills them); ``task`` is accepted and unused
        (no commissioning).
    """

    name = "pd-ref"
    #: Not among the oracle's starts (:func:`vcnc_baselines.optimal.search.causal_names`): a reference design is never
    #: the best start, and a new start would make every stored floor be solved again.
    oracle_start = False

    def __init__(self, layout, decision_period, nominal_parameters, plant=None, *, reference, dt, task=None):
        super().__init__(layout, decision_period, nominal_parameters, plant, reference=reference, dt=dt, task=None)
        if self.plant.servo_bandwidth is None:
            raise ValueError(f"plant {self.plant.name!r} declares no servo_bandwidth: pd-ref has no design for it")
        self._build()

    def _nominal_record(self):
        """No commissioning record: the design reads the declared nominal model only."""
        return None

    @property
    def bandwidth(self) -> float:
        """The PD's closed-loop double pole, rad/s: :data:`FRACTION` of the plant's ``servo_bandwidth``."""
        return FRACTION * float(self.plant.servo_bandwidth)

    def _build(self) -> None:
        kp, kd, ki = pid_gains(self.inverse.mass, self.inverse.damping, self.bandwidth, integral=False)
        table = reference_table(self.reference)  # zero feedforward and offsets: the loop alone
        self._set_law(table, ServoGains(np.asarray(kp, float), np.asarray(kd, float), np.asarray(ki, float)))

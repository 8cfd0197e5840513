"""Inverse-model feedforward plus PID: what every CNC feed drive runs (``ff-pid``).

The command of each axis is the commissioned machine's inverse dynamics along the reference (the identified
rigid body with its first mode, :mod:`vcnc_baselines.commissioning`), read ahead by half a control period and the
identified dead time, with the identified Coulomb friction of the direction of motion, the identified process
force along the path (:func:`~vcnc_baselines.inverse_model.path_force_feedforward`) and the backlash crossing
pre-compensated (:func:`vcnc_baselines.inverse_model.inverse_feedforward`), plus a PID on the measured tracking
error (derivative on ``v_d - v``, the measured velocity through the commissioned low-pass), its gains by pole
placement on the identified axis (:func:`vcnc_baselines.commissioning.design.pid_gains`: a triple closed-loop pole at the
commissioned bandwidth) and its output through the commissioned notch.  The law is :mod:`vcnc_baselines.servo`'s
with ``delta = delta' = 0`` and no coupling.

``commissioning`` says which record: ``"nominal"`` (default where the nominal machine has one: the shipped
identification run on the env's nominal machine), ``"machine"`` (``ff-pid@machine``: an identification run on
each plant before its episode), ``"model"`` (the rules on the declared model, no experiment).

A ``feedforward="shaper-zv"`` or ``"shaper-zvd"`` replaces the mode in the inverse by a ZV or ZVD input shaper
(Singer & Seering 1990) of the reference at the identified mode: the loop follows the shaped reference and the
feedforward is the rigid body's inverse along it (:func:`shaped_reference`); it costs contour accuracy on
curves, where the shaped path cuts inside the programmed one.
"""

from __future__ import annotations

import numpy as np

from vcnc_gym.envs import step_kernel as sk
from vcnc_gym.validation import non_negative, positive
from ..servo import OFFSET, VELOCITY_OFFSET, ServoGains, ServoPolicy, U_FF, reference_table
from ..inverse_model import inverse_feedforward, path_force_feedforward

__all__ = ["FeedforwardPIDPolicy", "shaped_reference"]


class FeedforwardPIDPolicy(ServoPolicy):
    """Inverse-model feedforward with friction and backlash pre-compensation, plus PID.

    Parameters
    ----------
    layout, decision_period, nominal_parameters, plant, reference, dt
        As :class:`~vcnc_baselines.servo.ServoPolicy` (:meth:`from_env` fills them).
    bandwidth : float, optional
        Closed-loop pole of the PID design, rad/s; default the commissioning record's.
    integral : bool
        PID (True, default) or PD.
    feedforward : bool or str
        Add the inverse-model input (True or ``"inverse"``, default: with the identified mode in it); False
        leaves the PID alone (the coupling controller ``ccc`` builds on that); ``"rigid"``: the inverse without
        the mode; ``"shaper-zv"``, ``"shaper-zvd"``: an input shaper of the reference at the mode and the rigid
        inverse along the shaped reference.
    friction_time : float, optional
        s, the Coulomb level's change at a reversal; default the plant's declaration
        (:attr:`vcnc_gym.plants.PlantModel.friction_time`).
    commissioning : str, optional
        ``"nominal"``, ``"machine"`` or ``"model"`` (:data:`vcnc_baselines.servo.COMMISSIONING_SOURCES`); None: the
        nominal machine's record where there is one, else the model's.
    backlash_time : float
        s; both as :func:`~vcnc_baselines.inverse_model.inverse_feedforward`.
    """

    name = "ff-pid"

    def __init__(
        self,
        layout,
        decision_period,
        nominal_parameters,
        plant=None,
        *,
        reference,
        dt,
        task=None,
        commissioning: str | None = None,
        bandwidth=None,
        integral: bool = True,
        feedforward=True,
        friction_time: float | None = None,
        backlash_time: float = 16e-3,
    ):
        super().__init__(
            layout,
            decision_period,
            nominal_parameters,
            plant,
            reference=reference,
            dt=dt,
            task=task,
            commissioning=commissioning,
        )
        self._bandwidth_override = None if bandwidth is None else positive("bandwidth", bandwidth, "rad/s")
        kinds = (True, False, "inverse", "rigid", "shaper-zv", "shaper-zvd")
        if not any(feedforward is k or (isinstance(k, str) and feedforward == k) for k in kinds):
            raise ValueError(f"feedforward must be one of {list(kinds)}, got {feedforward!r}")
        self.feedforward = "inverse" if feedforward is True else feedforward
        self.integral = bool(integral)
        self.friction_time = non_negative(
            "friction_time", self.plant.friction_time if friction_time is None else friction_time, "s"
        )
        self.backlash_time = non_negative("backlash_time", backlash_time, "s")
        self._build()

    @property
    def bandwidth(self) -> float:
        """The PID's closed-loop pole, rad/s (the first design row's, x axis)."""
        return self._bandwidth_override or self.records[0].designs[0].bandwidth

    def _build(self) -> None:
        tables, gains = [], []
        for record, inverse, g in self.commissioned():
            table = reference_table(self.reference)
            if self.feedforward:
                table[:] = self._feedforward_table(table, record, inverse)
            if not self.integral:
                g["ki"] = np.zeros(2)
            tables.append(table)
            gains.append(self._gains(g))
        self._set_law(tables[0] if len(tables) == 1 else np.stack(tables), gains[0] if len(gains) == 1 else gains)

    def _feedforward_table(self, table, record, inverse):
        """``table`` with the feedforward of :attr:`feedforward` (and a shaper's loop-reference offsets)."""
        if self.feedforward in ("shaper-zv", "shaper-zvd"):
            shaped = shaped_reference(self.reference, record, self.feedforward[7:], self.dt)
            rigid = record.inverse(with_mode=False)
            table[:, U_FF : U_FF + 2] = inverse_feedforward(
                rigid, shaped, self.dt, friction_time=self.friction_time, backlash_time=self.backlash_time
            )
            table[:, U_FF : U_FF + 2] += path_force_feedforward(record.process_force, shaped, self.dt, rigid.delay)
            table[:, OFFSET : OFFSET + 2] = (
                shaped[:, sk.REF_POSITION : sk.REF_POSITION + 2]
                - self.reference[:, sk.REF_POSITION : sk.REF_POSITION + 2]
            )
            table[:, VELOCITY_OFFSET : VELOCITY_OFFSET + 2] = (
                shaped[:, sk.REF_VELOCITY : sk.REF_VELOCITY + 2]
                - self.reference[:, sk.REF_VELOCITY : sk.REF_VELOCITY + 2]
            )
            return table
        inv = record.inverse(with_mode=False) if self.feedforward == "rigid" else inverse
        table[:, U_FF : U_FF + 2] = inverse_feedforward(
            inv, self.reference, self.dt, friction_time=self.friction_time, backlash_time=self.backlash_time
        )
        table[:, U_FF : U_FF + 2] += path_force_feedforward(record.process_force, self.reference, self.dt, inv.delay)
        return table

    def _gains(self, g: dict) -> ServoGains:
        """The law's gains from the axis PID's and filters (a coupling controller adds its own)."""
        return ServoGains(g["kp"], g["kd"], g["ki"], velocity_filter=g["velocity_filter"], notch=g["notch"])


def shaped_reference(samples: np.ndarray, record, kind: str, dt: float) -> np.ndarray:
    """The reference samples with position, velocity and acceleration through the ZV or ZVD shaper of each
    axis' identified mode (:func:`vcnc_baselines.commissioning.design.shaper`), each impulse rounded to whole
    control periods (the shaped signal of a linear shaper is the same combination of delayed samples; before
    the first sample the reference's start holds)."""
    from ..commissioning.design import shaper

    out = np.array(samples, dtype=np.float64, copy=True)
    for j, axis in enumerate(record.axes):
        times, amplitudes = shaper(axis, kind)
        for column in (sk.REF_POSITION, sk.REF_VELOCITY, sk.REF_ACCELERATION):
            x = samples[:, column + j]
            y = np.zeros_like(x)
            for t, a in zip(times, amplitudes):
                shift = int(round(t / dt))
                y += a * np.concatenate([np.full(shift, x[0]), x[: x.size - shift]]) if shift else a * x
            out[:, column + j] = y
    return out

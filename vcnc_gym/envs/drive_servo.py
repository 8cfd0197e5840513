"""The feed drives' own servo loop, closed inside the env's step: what the CNC's outer loop commands set-points to.

A machine tool's feed drive closes its position loop itself, every control period; the CNC above it sends
set-points.  The learnable ids (``action="setpoint"``, :class:`~vcnc_gym.envs.ContouringEnv`) do the same: the
agent's action moves the drive's set-point by up to ``setpoint_range`` mm per axis, held for a decision, and this
servo, compiled into the step kernel (:mod:`~vcnc_gym.envs.controller_contract`), turns it into the amplifier
command every control period ``T``.  Per axis ``j``, with ``E_j`` the measured tracking error ``x_d - x`` (mm),
``delta_j`` the agent's set-point correction (mm) and ``v`` the measured velocity (mm/s):

.. math::

    e_j &= \\mathrm{clip}(E_j + \\delta_j, \\pm 50\\, u_{max,j} / K_{p,j})  && \\text{mm}\\\\
    v_{f,j} &\\leftarrow a_j v_{f,j} + (1 - a_j) v_j                          && \\text{mm/s}\\\\
    u_j &= N_j\\big(K_{p,j} e_j + K_{d,j} (v_{d,j} - v_{f,j}) + K_{i,j} I_j\\big) && \\text{input unit}\\\\
    I_j &\\leftarrow \\mathrm{clip}(I_j + e_j T, \\pm u_{max,j} / K_{i,j})

``N_j`` a notch biquad at the machine's structural mode (none on the ideal plants).  This is the PID law of the
commissioned servo (``vcnc_baselines.servo``, the ``ff-pid`` controller without its feedforward table), and its
gains are the commissioning record of the id's nominal machine, shipped with the package in
``drive_servos.json`` (``tests/test_drive_servo.py`` holds them equal to ``vcnc_baselines``' records): on the shop
floor the machine's commissioned cascade, with its 45 degree phase margin and its notch, on the ideal plants the
same design rule on the ideal machine.  The derivative term on ``v_d - v`` is the drive's velocity feedforward.
"""

from __future__ import annotations

import hashlib
import json
from collections import namedtuple
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from numba import njit
from numba.extending import overload

from . import controller_contract

__all__ = ["DriveServoGains", "DriveServoArrays", "machine_key", "drive_servo_gains", "ERROR_LIMIT"]

#: The shipped gains of the drives' servos, by machine key (:func:`machine_key`).
GAINS_FILE = Path(__file__).with_name("drive_servos.json")

#: The position error the servo acts on is bounded at ``ERROR_LIMIT u_max / K_p`` per axis, as the commissioned
#: servo's (``vcnc_baselines.servo.ERROR_LIMIT``).
ERROR_LIMIT = 50.0

#: Memory columns per env: the axes' integrals (mm s), filtered velocities (mm/s), notch states (two per axis).
_M_I, _M_V, _M_N = 0, 2, 4
MEMORY = 8


@dataclass(frozen=True)
class DriveServoGains:
    """One machine's drive servo: per axis ``kp`` (input unit / mm), ``kd`` (input unit / (mm/s)), ``ki`` (input
    unit / (mm s)), the velocity low-pass pole ``velocity_pole`` in [0, 1) and the notch biquad ``notch`` (2, 5),
    ``(b0, b1, b2, a1, a2)``; ``key`` the machine it was commissioned on."""

    key: str
    kp: np.ndarray
    kd: np.ndarray
    ki: np.ndarray
    velocity_pole: np.ndarray
    notch: np.ndarray

    @classmethod
    def from_dict(cls, key: str, d: dict) -> "DriveServoGains":
        arrays = {name: np.asarray(d[name], dtype=np.float64) for name in ("kp", "kd", "ki", "velocity_pole")}
        notch = np.asarray(d["notch"], dtype=np.float64)
        for name, a in arrays.items():
            if a.shape != (2,) or not np.isfinite(a).all() or (a < 0).any():
                raise ValueError(f"{GAINS_FILE.name}: {key}: {name} must be two finite values >= 0, got {d[name]!r}")
        if notch.shape != (2, 5) or not np.isfinite(notch).all():
            raise ValueError(f"{GAINS_FILE.name}: {key}: notch must be (2, 5) finite, got {d['notch']!r}")
        if (arrays["kp"] <= 0).any() or (arrays["velocity_pole"] >= 1).any():
            raise ValueError(f"{GAINS_FILE.name}: {key}: kp must be > 0 and velocity_pole < 1")
        return cls(key, notch=notch, **arrays)

    def to_dict(self) -> dict:
        return {n: np.asarray(getattr(self, n)).tolist() for n in ("kp", "kd", "ki", "velocity_pole", "notch")}


def machine_key(plant, parameters, dt: float) -> str:
    """A commissioned machine's name: the plant's, shop floor or ideal, and a digest of its (nominal) parameters
    and the control period (``vcnc_baselines``' shipped commissioning records use the same key)."""
    from ..plants.shop_floor import ShopFloorModel

    shop = isinstance(plant, ShopFloorModel)
    p = np.ascontiguousarray(np.asarray(parameters, dtype=np.float64))
    digest = hashlib.sha1(p.tobytes() + np.float64(dt).tobytes()).hexdigest()[:12]
    return f"{plant.name}-{'shop' if shop else 'ideal'}-{digest}"


def _shipped() -> dict:
    try:
        return json.loads(GAINS_FILE.read_text())
    except (OSError, ValueError) as exc:
        raise ValueError(f"cannot read the drives' servo gains {GAINS_FILE}: {exc}") from None


def drive_servo_gains(plant, nominal_parameters, dt: float) -> DriveServoGains:
    """The shipped servo of the machine ``(plant, nominal_parameters, dt)``; ValueError naming the machine and the
    ids that have one otherwise (``servo_gains=`` gives a servo of one's own)."""
    key = machine_key(plant, nominal_parameters, dt)
    table = _shipped()
    if key not in table:
        raise ValueError(
            f"no commissioned drive servo is shipped for this machine ({key}: plant {plant.name!r}, dt {dt:g} s, "
            f"its nominal parameters); the shipped ones are {sorted(table)}. Pass servo_gains={{'kp': [..], "
            f"'kd': [..], 'ki': [..], 'velocity_pole': [..], 'notch': [[1, 0, 0, 0, 0]] * 2}} or action='voltage'"
        )
    return DriveServoGains.from_dict(key, table[key])


#: The compiled servo of N envs: ``memory`` (N, MEMORY), ``setpoint`` (N, 2) mm, the gains (2,) and ``notch``
#: (2, 5) (the identity ``(1, 0, 0, 0, 0)``: no notch), the integral's and the error's bounds (2,), ``u_max`` (N, 2)
#: input unit, ``dt`` (s).
DriveServoArrays = namedtuple(
    "DriveServoArrays",
    ["memory", "setpoint", "kp", "kd", "ki", "integral_limit", "error_limit", "velocity_pole", "notch", "u_max", "dt"],
)


def servo_arrays(gains: DriveServoGains, n_envs: int, u_max: np.ndarray, dt: float) -> DriveServoArrays:
    """The compiled servo of ``n_envs`` envs with ``gains``; ``u_max`` (2,) the nominal input limits (each env's
    own are set at its reset)."""
    u = np.repeat(np.asarray(u_max, dtype=np.float64)[None], n_envs, axis=0)
    ki = gains.ki.copy()
    limit = np.where(ki > 0, u[0] / np.where(ki > 0, ki, 1.0), 0.0)
    return DriveServoArrays(
        np.zeros((n_envs, MEMORY)),
        np.zeros((n_envs, 2)),
        gains.kp.copy(),
        gains.kd.copy(),
        ki,
        limit,
        ERROR_LIMIT * u[0] / gains.kp,
        gains.velocity_pole.copy(),
        np.ascontiguousarray(gains.notch),
        u,
        np.float64(dt),
    )


@njit(cache=True, _nrt=False)
def _drive_command(s, i, obs, o, out):
    """Env ``i``'s servo command u / u_max (float32 values, clipped to [-1, 1]) for the period's observation."""
    mem = s.memory[i]
    for j in range(2):
        e = min(max(np.float64(obs[o.tracking_error + j]) + s.setpoint[i, j], -s.error_limit[j]), s.error_limit[j])
        a = s.velocity_pole[j]
        vf = a * mem[_M_V + j] + (1.0 - a) * np.float64(obs[o.velocity + j])
        mem[_M_V + j] = vf
        integral = mem[_M_I + j]
        x = s.kp[j] * e + s.kd[j] * (np.float64(obs[o.reference_velocity + j]) - vf) + s.ki[j] * integral
        c = s.notch[j]
        y = c[0] * x + mem[_M_N + 2 * j]
        mem[_M_N + 2 * j] = c[1] * x - c[3] * y + mem[_M_N + 2 * j + 1]
        mem[_M_N + 2 * j + 1] = c[2] * x - c[4] * y
        limit = s.integral_limit[j]
        mem[_M_I + j] = min(max(integral + e * s.dt, -limit), limit)
        out[j] = np.float32(min(max(y / s.u_max[i, j], -1.0), 1.0))


@overload(controller_contract.command, jit_options={"cache": True})
def _command(controller, i, obs, o, out):
    if controller_contract.is_controller(controller, DriveServoArrays):
        return lambda controller, i, obs, o, out: _drive_command(controller, i, obs, o, out)

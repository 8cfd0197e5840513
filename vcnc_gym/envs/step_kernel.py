"""The compiled inner loop of :class:`ContouringEnv`: one decision step.

One call advances the plant by ``action_repeat`` control periods, measures the
contour error against the whole contour and writes the observation, so a
Python ``step`` makes exactly one numba call.  No validation here: the env
checks its inputs before calling.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from ..contour.projector import project_point
from ..plants.vcnc_feed_drive import IDX_U_MAX, step_feed_drives, table_velocity

# columns of the packed reference array (K, REF_COLUMNS)
REF_POSITION = 0  # x_d (2) mm
REF_VELOCITY = 2  # dx_d/dt (2) mm/s
REF_ACCELERATION = 4  # d2x_d/dt2 (2) mm/s^2
REF_TANGENT = 6  # unit path tangent at x_d (2)
REF_COLUMNS = 8

# slots of the per-step result vector written next to the observation
OUT_CONTOUR_ERROR = 0  # mm, at the end of the step
OUT_CONTOUR_ERROR_MEAN = 1  # mm, mean over the repeated control periods
OUT_CONTOUR_ERROR_MAX = 2  # mm, max over the repeated control periods
OUT_POSITION = 3  # (2) mm
OUT_REFERENCE_POSITION = 5  # (2) mm
OUT_TRACKING_ERROR = 7  # (2) mm
OUT_FINITE = 9  # 1.0 if the plant state is finite
OUT_COMMAND = 10  # (2) V, the amplifier output after saturation
OUT_SIZE = 12


@njit(cache=True)
def contouring_step(
    k0, n_repeat, voltage, state, params, dt, n_substeps,
    reference, preview_steps, obs_offsets, obs_high, previous_action,
    control_points, weights, knots, degree,
    piece_u, piece_table, piece_sag, grid_origin, cell_size, grid_shape, cell_start, cell_pieces,
    der, work, obs, result,
):
    """Advance ``n_repeat`` control periods from reference index ``k0``.

    Parameters
    ----------
    k0 : int
        Reference sample index at the start of the step.
    voltage : (1, 2) float64
        Amplifier command in V, held over the step (the plant saturates it).
    state, params : plant arrays of :mod:`vcnc_gym.plants.vcnc_feed_drive`, N = 1.
    reference : (K, REF_COLUMNS) float64
        Packed reference; past its end the last sample holds.
    obs_offsets : int64 array
        Offsets of the layout fields, in :class:`ObservationLayout` order.
    obs, result : float32 (obs_dim,) and float64 (OUT_SIZE,) outputs.

    Returns
    -------
    int
        The reference index after the step.
    """
    last = reference.shape[0] - 1
    k = k0
    err_sum = 0.0
    err_max = 0.0
    err = 0.0
    for j in range(max(n_repeat, 1)):
        if n_repeat > 0:  # n_repeat = 0 only observes (at reset)
            step_feed_drives(state, voltage, params, dt, n_substeps)
            k += 1
        err, _foot_u = project_point(
            state[0, 0, 2], state[0, 1, 2], control_points, weights, knots, degree,
            piece_u, piece_table, piece_sag, grid_origin, cell_size, grid_shape, cell_start,
            cell_pieces, der, work,
        )
        err_sum += err
        if err > err_max:
            err_max = err
    kr = min(k, last)
    x = state[0, 0, 2]
    y = state[0, 1, 2]
    ex = reference[kr, REF_POSITION] - x
    ey = reference[kr, REF_POSITION + 1] - y
    tx = reference[kr, REF_TANGENT]
    ty = reference[kr, REF_TANGENT + 1]

    finite = np.isfinite(x) and np.isfinite(y) and np.isfinite(state[0, 0, 1]) and np.isfinite(state[0, 1, 1])
    result[OUT_CONTOUR_ERROR] = err
    result[OUT_CONTOUR_ERROR_MEAN] = err_sum / max(n_repeat, 1)
    result[OUT_CONTOUR_ERROR_MAX] = err_max
    result[OUT_POSITION] = x
    result[OUT_POSITION + 1] = y
    result[OUT_REFERENCE_POSITION] = reference[kr, REF_POSITION]
    result[OUT_REFERENCE_POSITION + 1] = reference[kr, REF_POSITION + 1]
    result[OUT_TRACKING_ERROR] = ex
    result[OUT_TRACKING_ERROR + 1] = ey
    result[OUT_FINITE] = 1.0 if finite else 0.0
    for i in range(2):
        result[OUT_COMMAND + i] = min(params[0, i, IDX_U_MAX], max(-params[0, i, IDX_U_MAX], voltage[0, i]))

    # observation, field by field in ObservationLayout order
    o = obs_offsets
    for j in range(6):  # reference position, velocity, acceleration
        obs[o[0] + j] = reference[kr, j]
    obs[o[3]] = ex
    obs[o[3] + 1] = ey
    obs[o[4]] = err
    obs[o[5]] = tx * ex + ty * ey  # seed 002 eq. (3): e_l = R^T e_w
    obs[o[6]] = -ty * ex + tx * ey
    for i in range(2):
        obs[o[7] + i] = table_velocity(state[0, i, 0], state[0, i, 1], state[0, i, 2],
                                       params[0, i, 0], params[0, i, 9])
    for j in range(preview_steps.shape[0]):
        kp = min(kr + preview_steps[j], last)
        obs[o[8] + 2 * j] = reference[kp, REF_POSITION] - x
        obs[o[8] + 2 * j + 1] = reference[kp, REF_POSITION + 1] - y
    obs[o[9]] = previous_action[0]
    obs[o[9] + 1] = previous_action[1]
    for j in range(obs.shape[0]):
        v = obs[j]
        if not np.isfinite(v):
            obs[j] = 0.0
        elif v > obs_high[j]:
            obs[j] = obs_high[j]
        elif v < -obs_high[j]:
            obs[j] = -obs_high[j]
    return k

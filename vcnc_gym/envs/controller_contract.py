"""The controller contract: a classical controller compiled into the step kernel.

A controller that runs every control period (the residual action mode's
baseline) costs a Python call per period when it runs as a policy's
``predict``; compiled into the kernel, a whole decision of N envs (``repeat``
control periods, each with the controller's command) is one numba call
(:func:`vcnc_gym.envs.step_kernel.step_controlled_parallel`).  The core package names
no controller: a controller's module (in :mod:`vcnc_baselines`) declares

- a ``namedtuple`` class holding its per-env memory, first (an array
  whose first axis is the env, shared with the Python policy, so that
  resetting the policy's memory resets the compiled controller's), then its
  gains and any per-env scratch;
- a numba overload of :func:`command` for that class::

      @overload(controller_contract.command, jit_options={"cache": True})
      def _command(controller, i, obs, o, out):
          if controller_contract.is_controller(controller, MyArrays):
              return lambda controller, i, obs, o, out: ...

Kernel
------
``command(controller, i, obs, o, out)``
    The normalised command u / u_max of env ``i`` ((2,) written into ``out``,
    float64 holding float32 values, clipped to [-1, 1]) from its observation
    ``obs`` (float32, laid out by the offsets ``o``,
    :data:`~vcnc_gym.envs.layout.ObservationOffsets`), advancing env ``i``'s
    memory by one period: what the policy's ``predict`` returns for that
    observation, to the bit.
"""

from __future__ import annotations

from numba import njit, types

__all__ = ["commands_entry", "command", "commands", "is_controller", "check_controller"]


def command(controller, i, obs, o, out):  # pragma: no cover - compiled per controller through numba overloads
    """Env ``i``'s normalised command into ``out``; see the module docstring."""
    raise NotImplementedError("command() runs in numba code, implemented by each controller module's overload")


def is_controller(numba_type, arrays_class) -> bool:
    """True if ``numba_type`` (an overload's argument type) is ``arrays_class``, a controller's namedtuple."""
    return isinstance(numba_type, types.BaseNamedTuple) and numba_type.instance_class is arrays_class


@njit(cache=True)
def commands(controller, obs, o, out):
    """:func:`command` for every env of a batch: ``obs`` (N, D) float32, ``out`` (N, 2) (a policy's ``predict``)."""
    for i in range(obs.shape[0]):
        command(controller, i, obs[i], o, out[i])


def commands_entry(controller, obs, offsets, out):
    """:func:`commands`' compiled entry point for the numba types of these arguments (compiled if it was not):
    called directly it skips the dispatcher's typing of every argument on every call, which for a controller's
    namedtuple of a dozen arrays costs about 10 us against 2 us for the call itself (a policy's ``predict`` runs
    once per control period).  The caller must pass arguments of the same types (dtype, layout, writability)."""
    from numba import typeof

    sig = tuple(typeof(a) for a in (controller, obs, offsets, out))
    if sig not in commands.overloads:
        commands.compile(sig)
    return commands.overloads[sig].entry_point


def check_controller(controller, n_envs: int):
    """``controller`` if it is a compiled controller for ``n_envs`` envs (a namedtuple whose first field, the
    memory, has ``n_envs`` rows); ValueError otherwise (the kernels index it unchecked)."""
    fields = getattr(controller, "_fields", None)
    if not isinstance(controller, tuple) or not fields:
        raise ValueError(
            f"controller must be a compiled controller (BaselinePolicy.compiled(n_envs), a namedtuple), "
            f"got {type(controller).__name__}"
        )
    memory = controller[0]
    if not hasattr(memory, "shape") or memory.ndim < 1 or memory.shape[0] != n_envs:
        raise ValueError(
            f"controller's memory {fields[0]!r} must have {n_envs} rows (one per env), got shape "
            f"{getattr(memory, 'shape', None)}"
        )
    return controller

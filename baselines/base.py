"""The common base of the classical baselines: an SB3-compatible ``predict``.

Every baseline is a policy with Stable-Baselines3's signature::

    action, state = policy.predict(observation, state=None,
                                   episode_start=None, deterministic=True)

so that :func:`stable_baselines3.common.evaluation.evaluate_policy` and any
loop written for an SB3 agent run a classical controller unchanged.

A controller has memory (filter states, integrators, adaptive estimates).  It
is kept inside the policy, one row per environment of the batch, allocated
when the first observation shows the batch size and reset for every
environment whose ``episode_start`` is True.  The ``state`` argument of SB3
(the hidden state of a recurrent network) is passed through untouched.
"""

from __future__ import annotations

import numpy as np

from vcnc_gym.envs import controller_contract
from vcnc_gym.plants import get_plant
from vcnc_gym.validation import positive

__all__ = ["BaselinePolicy"]


class BaselinePolicy:
    """Base class of the classical controllers, with SB3's ``predict``.

    Parameters
    ----------
    layout : vcnc_gym.envs.layout.ObservationLayout
        Names the fields of the observation.
    decision_period : float
        Period in s at which :meth:`predict` is called (the env's
        ``dt * action_repeat``); discrete controllers are discretised at it.
    nominal_parameters : array_like, shape (2, P)
        Nominal parameters of the x and y axes of the plant, columns named by
        ``plant.parameter_names``.  The input limit (the plant's
        ``input_limit`` parameter, e.g. ``u_max`` in V) scales the action.
    plant : str or vcnc_gym.plants.PlantModel, optional
        The plant the env holds; default the first of :attr:`plants`.  It must
        be one of :attr:`plants`: a controller is designed for its paper's
        machine.

    Notes
    -----
    Subclasses set :attr:`plants`, :attr:`state_shape` (the per-env shape of
    their memory, ``(0,)`` for none) and implement :meth:`_initial_state` and
    :meth:`_command`.  The action returned is ``clip(u / u_lim, -1, 1)`` as
    float32, u the axis command in the plant's input unit and u_lim its limit.
    """

    #: Registry name, set by each subclass.
    name: str = "base"
    #: Names of the plants (``vcnc_gym.plants`` modules) the controller is designed for (:meth:`designed_for`).
    plants: tuple[str, ...] = ()
    #: The source paper that designed this controller, by authors and year ("" for the suite's own designs): the
    #: bench's plots show a paper's controllers beside the strongest causal one.
    paper: str = ""
    #: False for a controller whose episode costs minutes in Python (``mpc``'s QP per period): ``vcnc-bench`` runs
    #: it when named or with ``--all``, not in its default table.
    in_default_table: bool = True
    #: Per-environment shape of the controller memory; (0,) for a memoryless controller.
    state_shape: tuple = (0,)

    @classmethod
    def designed_for(cls, plant) -> bool:
        """True if the controller applies to ``plant`` (a ``PlantModel``): by default, if it is one of
        :attr:`plants`; a model-based design overrides it to take any plant that declares what it needs."""
        return plant.name in cls.plants

    def __init__(self, layout, decision_period: float, nominal_parameters, plant=None):
        for attr in ("size", "slice"):
            if not hasattr(layout, attr):
                raise ValueError(f"layout must be an ObservationLayout (missing {attr!r}), got {type(layout).__name__}")
        self.layout = layout
        self.decision_period = positive("decision_period", decision_period, "s")
        if plant is None:
            if not self.plants:
                raise ValueError(f"{type(self).__name__} declares no plant; pass plant=")
            plant = self.plants[0]
        self.plant = get_plant(plant)
        if not type(self).designed_for(self.plant):
            raise ValueError(
                f"baseline {self.name!r} is not designed for the plant {self.plant.name!r}"
                + (
                    f" (it is for {list(self.plants)})"
                    if self.plants
                    else " (it needs a plant that declares its inverse dynamics and servo_bandwidth)"
                )
            )
        p = np.asarray(nominal_parameters)
        if p.dtype.kind not in "iuf":
            raise ValueError(f"nominal_parameters must be numeric, got dtype {p.dtype}")
        if p.shape != (2, self.plant.n_parameters):
            raise ValueError(f"nominal_parameters must have shape (2, {self.plant.n_parameters}), got {p.shape}")
        self.nominal_parameters = self.plant.validate(p)[0]
        self.u_max = self.plant.input_limits(self.nominal_parameters).copy()
        self._state = None  # (n_envs, *state_shape), allocated on the first predict
        self._compiled = None  # (the memory it wraps, the compiled form) once predict has built it
        self._entry = None  # (the observations' writability, commands' compiled entry point for them)
        self._offsets = layout.offsets() if hasattr(layout, "offsets") else None
        if getattr(layout, "is_scaled", False):
            raise ValueError(
                "a classical controller reads the observation in its physical units: make the env with "
                "action='voltage', observation_scale='raw' and action_repeat=1 (the v1 interface), or use base= "
                "to run it inside a learnable env's step"
            )

    # -- construction from an env -------------------------------------------
    @classmethod
    def from_env(cls, env, **params):
        """Build the controller for ``env``: its layout, decision period (s), plant and nominal parameters.

        ``env`` is a (wrapped) Gymnasium env or vector env, read through
        ``env.unwrapped``, or an SB3 ``VecEnv`` of such envs, read through
        ``get_attr`` (all its envs must share the decision period; the first
        env's layout and nominal plant are used).
        """
        names = ("layout", "decision_period", "nominal_parameters")
        if hasattr(env, "get_attr") and hasattr(env, "env_method"):  # an SB3 VecEnv
            try:
                values = [env.get_attr(a) for a in names]
            except AttributeError as exc:
                raise ValueError(f"the VecEnv's envs lack {exc}; are they vcnc_gym envs?") from None
            periods = values[1]
            if any(not np.isclose(p, periods[0], rtol=1e-12, atol=0.0) for p in periods):
                raise ValueError(f"the VecEnv's envs have different decision periods {periods}")
            layout, period, nominal = (v[0] for v in values)
            try:
                plant = env.get_attr("plant")[0]
            except AttributeError:
                plant = None
        else:
            u = getattr(env, "unwrapped", env)
            missing = [a for a in names if not hasattr(u, a)]
            if missing:
                raise ValueError(f"env.unwrapped lacks {missing}; is it a vcnc_gym env?")
            layout, period, nominal = u.layout, u.decision_period, u.nominal_parameters
            plant = getattr(u, "plant", None)  # None: the controller's own plant
        return cls(layout=layout, decision_period=period, nominal_parameters=nominal, plant=plant, **params)

    # -- memory ------------------------------------------------------------
    @property
    def n_envs(self) -> int:
        """Batch size of the memory currently held (0 before the first predict)."""
        return 0 if self._state is None else self._state.shape[0]

    @property
    def controller_state(self):
        """The per-env controller memory, shape ``(n_envs, *state_shape)``, or None before the first predict."""
        return self._state

    def _initial_state(self) -> np.ndarray:
        """Memory of one env at the start of an episode, shape :attr:`state_shape`."""
        return np.zeros(self.state_shape)

    def reset(self, n_envs: int | None = None, mask=None) -> None:
        """Reset the memory of every env, or of those where ``mask`` is True.

        ``n_envs`` (re)allocates the memory for that batch size first.
        """
        if n_envs is not None:
            self._state = np.empty((int(n_envs),) + tuple(self.state_shape))
            mask = None
        if self._state is None:
            return
        init = self._initial_state()
        if mask is None:
            self._state[...] = init
        else:
            self._state[np.asarray(mask, dtype=bool)] = init

    # -- SB3 interface -----------------------------------------------------
    def predict(self, observation, state=None, episode_start=None, deterministic=True):
        """Action for one observation or a batch, SB3's signature.

        Parameters
        ----------
        observation : array_like, shape (obs_dim,) or (n_envs, obs_dim)
            Observation(s) laid out by :attr:`layout` (mm, mm/s, mm/s^2).
        state : any
            Passed through unchanged (SB3's recurrent state; the controller
            keeps its own memory).
        episode_start : array_like of bool, shape (n_envs,) or scalar, optional
            True where an episode has just begun: that env's controller
            memory is reset before the action is computed.  Memory is also
            reset on the first call and whenever the batch size changes.
        deterministic : bool
            Ignored: the controllers are deterministic.

        Returns
        -------
        action : ndarray of float32, shape (2,) or (n_envs, 2)
            Normalised axis commands u / u_max, clipped to [-1, 1].
        state : any
            The ``state`` argument.
        """
        obs = np.asarray(observation)
        single = obs.ndim == 1
        obs2 = obs.reshape(1, -1) if single else obs
        if obs2.ndim != 2 or obs2.shape[1] != self.layout.size:
            raise ValueError(
                f"observation must have shape ({self.layout.size},) or (n_envs, {self.layout.size}), got {obs.shape}"
            )
        n = obs2.shape[0]
        start = None
        if episode_start is not None:
            start = np.asarray(episode_start, dtype=bool).reshape(-1)
            if start.size == 1 and n > 1:
                start = np.repeat(start, n)
            if start.size != n:
                raise ValueError(f"episode_start has {start.size} entries for {n} observations")
        if self._state is None or self._state.shape[0] != n:
            self.reset(n_envs=n)
        elif start is not None and (start[0] if n == 1 else start.any()):  # (a reduction costs 3 us a call)
            self.reset(mask=start)
        form = None
        if obs2.dtype == np.float32:  # the env's dtype: the compiled law, if any (rebuilt when the memory is)
            if self._compiled is None or self._compiled[0] is not self._state:
                self._compiled = (self._state, self._compiled_arrays())
                self._entry = None
            form = self._compiled[1]
        if form is not None:  # the same numbers as _command's (benchmarks/baseline_predict.py: 2-3x faster)
            out = np.empty((n, 2))
            x = np.ascontiguousarray(obs2)
            kind = x.flags.writeable  # with the dtype (float32) and layout (C), what sets x's numba type
            if self._entry is None or self._entry[0] != kind:
                self._entry = (kind, controller_contract.commands_entry(form, x, self._offsets, out))
            self._entry[1](form, x, self._offsets, out)
            action = out.astype(np.float32)
        else:
            u = self._command(obs2)
            action = np.clip(u / self.u_max, -1.0, 1.0).astype(np.float32)
        return (action[0] if single else action), state

    def _command(self, obs: np.ndarray) -> np.ndarray:
        """Axis commands in the plant's input unit (V, A), (n_envs, 2), for a batch of observations;
        updates the memory."""
        raise NotImplementedError

    def compiled(self, n_envs: int):
        """The controller for the step kernel, or None if it has no compiled form.

        A controller with one returns its module's namedtuple of gains and
        memory (:mod:`vcnc_gym.envs.controller_contract`), the memory being
        this policy's, allocated for ``n_envs`` and reset: the native vector
        env then runs the controller inside its compiled step, with the same
        commands, to the bit, as :meth:`predict`.
        """
        self.reset(n_envs=n_envs)
        return self._compiled_arrays()

    def _compiled_arrays(self):
        """The compiled form around the current memory, or None (the default: no compiled form).

        A subclass with one states its law twice: :meth:`_command` in NumPy,
        the readable statement, and a numba ``controller_contract.command``
        overload doing the same floating-point operations, which
        :meth:`predict` runs on float32 observations (a test holds the two
        equal to the bit).
        """
        return None

    def __repr__(self) -> str:
        return f"{type(self).__name__}(decision_period={self.decision_period:g} s)"

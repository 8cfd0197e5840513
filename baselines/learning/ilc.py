"""The iterative learning contouring controller of Simba et al., eqs. (8)-(11), and K trials of it.

Simba et al. repeat the same contour and, between trials j and
j + 1, learns from the normal component of the error only:

.. math::

    e_{vn} = R_n e_w, \\qquad
    v_{j+1}(t) = Q \\big[v_j(t) + L\\, e_{vn,j}(t)\\big] + K e_{l,j+1}(t)
    \\qquad (8), (9)

with the variable-gain PID learning function of eq. (11),

.. math::

    L e_{vn,j}(t) = \\Psi_P K_{PL} e_{vn,j}(t)
        + \\Psi_I K_{IL} \\textstyle\\sum_{\\tau < t} e_{vn,j}(\\tau) T
        + \\Psi_D K_{DL} \\big(e_{vn,j}(t) - e_{vn,j}(t-1)\\big) / T,
    \\qquad \\psi_{m,i} = 1 - \\frac{1}{\\alpha} \\mathrm{sat}\\!\\left(\\frac{e_{vn,j,i}(t)}{\\beta}\\right),

Table I: k_PL = 200, k_IL = 0.2, k_DL = 10, alpha = 30, beta = 0.005 mm, q = 1.

How the equations are read
--------------------------
* **v_j is the whole virtual input of trial j** (eq. (9): "the system control
  input in the j-th iteration"), feedback included: the previous trial's
  feedback becomes part of the next trial's feedforward ("a control loop with
  previous and current signal cycles"; the current-cycle-feedback ILC of the
  literature).  ``K e_{l,j+1}`` is the full feedback of eq. (7) in the
  current trial (path-frame PD and the theta terms).  The reference
  acceleration x_d'', the same in every trial, is kept out of the stored and
  filtered part: v_{j+1} = x_d'' + Q[w_j + L e_vn,j] + K e_{l,j+1} with
  w_j = v_j - x_d''.  With Q = 1 this is eq. (9) exactly, and trial 1
  (w_0 = 0) is the contouring controller of eq. (7),
  :class:`~vcnc_baselines.coupling.contouring_fb.ContouringFBPolicy`.
* **The stored v_j(t) is what was applied**: the current after the
  amplifier's limit, mapped back through eq. (5)
  (:meth:`~vcnc_baselines.coupling.contouring_fb.ContouringFBPolicy.applied_acceleration`).
  Storing the unsaturated demand would let the stored input grow trial after
  trial wherever the current saturates (learning wind-up).
* **R_n is the projection on the path normal**, N N^T with
  N = (-sin theta, cos theta): e_vn = e_n N.  Eq. (8) prints the first row
  with the opposite sign ([-sin^2, sin cos]), which would turn the x
  component of the learning into positive feedback wherever sin theta != 0.
* **Units**: as for eq. (7) (see :mod:`vcnc_baselines.coupling.contouring_fb`), Table I's
  "A" gains act on the virtual input, an acceleration: k_PL in 1/s^2,
  k_IL in 1/s^3 (on the time integral of e_vn), k_DL in 1/s (on its
  derivative, the backward difference over T).  So the learning does not
  depend on the control period.
* **Psi**: one factor per axis and term, from that axis' component of
  e_vn,j(t), signed as printed (between 1 - 1/alpha and 1 + 1/alpha: +-3.3 %
  with Table I).  alpha and beta are the same for P, I and D (Table I gives
  one value each).
* **Q(b^-1)** is ``q`` (Table I: 1), times, if ``q_cutoff`` is given, a
  zero-phase low-pass (second-order Butterworth run forwards and backwards
  over the finished trial: ``|Q|`` = q / (1 + (f / q_cutoff)^4)).

Convergence, and the ``ilc-q`` variant
--------------------------------------
With the stored feedback the trial-to-trial map of the error is, for the
linear loop, e_{j+1} = Q S_i (1 - G L) e_j, S_i = 1 / (1 + loop gain) the
sensitivity of the sampled eq. (7) loop (G = 1/s^2 after eq. (5)): learning
is fast below the loop's bandwidth (``|S_i|`` << 1), but ``|S_i|`` exceeds 1 from
38.5 Hz on, peaking at 1.26 near 55 Hz (dt = 0.1 ms; 1.51 at 1 ms), and L
(k_PL = 200 1/s^2 against k_P = 70 000) cannot pull it back.  With Table I's
q = 1 the error content there grows by up to 26 % per trial: the ringing
after a sharp corner or a friction break-away builds up over the trials (the
paper's own ILC gains 9 % on its linear path).  The registered variant
``ilc-q`` adds the low-pass with q_cutoff = 20 Hz (``|Q|`` = 0.07 at 38.5 Hz):
then ``|Q S_i (1 - G L)|`` <= 0.13 at every frequency (computed for the sampled
loop at 0.1 ms), a monotone convergence of the linear loop, at the price of
learning little above about 20 Hz.

Trials and memory
-----------------
Each episode is one trial.  The policy counts its :meth:`predict` calls since
the env's ``episode_start``; that count t indexes the stored sequences.  At
the next ``episode_start`` of the same env the trial just run (its applied
w_j(t) and e_vn,j(t), t < T_j) becomes the learned input Q[w_j + L e_vn,j](t)
of the next trial, computed once then.  Where a trial runs longer than the
previous one (e.g. after a diverged trial), t >= T_j gets no learned input,
as in trial 1.

The learning memory survives ``episode_start`` and :meth:`reset` with a mask;
:meth:`reset_learning` forgets it (back to trial 1), and so does a change of
the batch size (the memory is per env of the batch).  Batched over n_envs
like every baseline: env i of the batch is its own sequence of trials.

Running K trials::

    import gymnasium as gym, vcnc_gym, baselines
    from vcnc_baselines.learning.ilc import run_trials
    env = gym.make("VCNC-CornersSmooth-v1")
    policy = vcnc_baselines.make("ilc", env)             # or "ilc-q" (20 Hz low-pass Q)
    results = run_trials(policy, env, 10)          # ten EpisodeResults, trial 1 first
    [r.max_contour_error_um for r in results]
    policy.reset_learning()                        # forget: the next episode is trial 1 again

``run_trials`` is :func:`vcnc_gym.evaluation.run_episode` K times with the
same policy object (and the same seed, so the same plant); with a VecEnv,
SB3's ``evaluate_policy(policy, venv, n_eval_episodes=K)`` runs K trials per
env the same way.
"""

from __future__ import annotations

import numpy as np

from vcnc_gym.validation import positive, non_negative
from ..coupling.contouring_fb import TABLE_I_FB, ContouringFBPolicy

__all__ = ["TABLE_I_ILC", "ILCPolicy", "run_trials"]

#: Simba et al., Table I: learning gains (k_PL 1/s^2, k_IL 1/s^3, k_DL 1/s), alpha, beta (mm), q.
TABLE_I_ILC = {"k_pl": 200.0, "k_il": 0.2, "k_dl": 10.0, "alpha": 30.0, "beta": 0.005, "q": 1.0}

_INITIAL_CAPACITY = 4096


class ILCPolicy(ContouringFBPolicy):
    """Simba et al.'s iterative learning contouring controller, eqs. (8)-(11), Table I.

    Parameters
    ----------
    layout, decision_period, nominal_parameters, plant, k_p, k_d
        As :class:`~vcnc_baselines.coupling.contouring_fb.ContouringFBPolicy` (the feedback
        K e_l of eq. (9) is its eq. (7)).
    k_pl : float
        Proportional learning gain in 1/s^2, >= 0.  Default 200.
    k_il : float
        Integral learning gain in 1/s^3, >= 0.  Default 0.2.
    k_dl : float
        Derivative learning gain in 1/s, >= 0.  Default 10.
    alpha : float
        Variable-gain constant of eq. (11), > 1 (the gains stay positive).  Default 30.
    beta : float
        Error scale of eq. (11) in mm, > 0.  Default 0.005.
    q : float
        The constant of the Q filter of eq. (9), in (0, 1].  Default 1 (Table I).
    q_cutoff : float or None
        Cutoff in Hz of Q's zero-phase low-pass, below the Nyquist frequency;
        None (default, as in Simba et al.): no low-pass.  ``ilc-q`` uses 20 Hz.

    Attributes
    ----------
    trials_done : ndarray of int, (n_envs,)
        Completed trials per env whose data the current trial learns from
        (0 in the first trial).
    """

    name = "ilc"
    #: Each episode is a trial learning from the previous one (``vcnc-bench --trials K`` runs K of them).
    learns_across_episodes = True

    def __init__(
        self,
        layout,
        decision_period,
        nominal_parameters,
        plant=None,
        k_p=TABLE_I_FB["k_p"],
        k_d=TABLE_I_FB["k_d"],
        k_pl=TABLE_I_ILC["k_pl"],
        k_il=TABLE_I_ILC["k_il"],
        k_dl=TABLE_I_ILC["k_dl"],
        alpha=TABLE_I_ILC["alpha"],
        beta=TABLE_I_ILC["beta"],
        q=TABLE_I_ILC["q"],
        q_cutoff=None,
    ):
        super().__init__(layout, decision_period, nominal_parameters, plant, k_p=k_p, k_d=k_d)
        self.k_pl = non_negative("k_pl (1/s^2)", k_pl)
        self.k_il = non_negative("k_il (1/s^3)", k_il)
        self.k_dl = non_negative("k_dl (1/s)", k_dl)
        self.alpha = positive("alpha", alpha)
        if self.alpha <= 1.0:
            raise ValueError(f"alpha must be > 1 (psi = 1 - sat(e/beta)/alpha stays positive), got {self.alpha}")
        self.beta = positive("beta (mm)", beta)
        self.q = positive("q", q)
        if self.q > 1.0:
            raise ValueError(f"q must be in (0, 1], got {self.q}")
        self.q_cutoff = None if q_cutoff is None else positive("q_cutoff (Hz)", q_cutoff)
        if self.q_cutoff is not None and self.q_cutoff >= 0.5 / self.decision_period:
            raise ValueError(
                f"q_cutoff must be below the Nyquist frequency {0.5 / self.decision_period:g} Hz, "
                f"got {self.q_cutoff:g} Hz"
            )
        self.reset_learning()

    # -- learning memory ---------------------------------------------------------
    def reset_learning(self) -> None:
        """Forget every trial: the next episode of every env is trial 1 (the plain eq. (7) controller)."""
        self._state = None
        self._t = None  # (n,) control periods since episode_start
        self._record_w = None  # (n, cap, 2) applied v - x_d'' of the running trial, mm/s^2
        self._record_e = None  # (n, cap, 2) its e_vn, mm
        self._learned = None  # (n, cap, 2) Q[v_j - x_d'' + L e_vn,j] for the running trial, mm/s^2
        self._learned_len = None  # (n,) T_j: how much of it is defined
        self._ended = None  # (n,) bool: the env's episode has ended, its calls until the next start are not recorded
        self.trials_done = np.zeros(0, dtype=np.int64)

    def _allocate(self, n: int) -> None:
        self._t = np.zeros(n, dtype=np.int64)
        self._ended = np.zeros(n, dtype=bool)
        self._record_w = np.zeros((n, _INITIAL_CAPACITY, 2))
        self._record_e = np.zeros((n, _INITIAL_CAPACITY, 2))
        self._learned = np.zeros((n, _INITIAL_CAPACITY, 2))
        self._learned_len = np.zeros(n, dtype=np.int64)
        self.trials_done = np.zeros(n, dtype=np.int64)

    def reset(self, n_envs: int | None = None, mask=None) -> None:
        """Start a new trial for every env (or those where ``mask`` is True), keeping what was learned.

        A new batch size ``n_envs`` forgets the learning (it is per env).
        """
        if n_envs is not None and (self._t is None or self._t.shape[0] != int(n_envs)):
            self._allocate(int(n_envs))
        elif self._t is not None:
            rows = np.arange(self._t.shape[0]) if mask is None else np.flatnonzero(np.asarray(mask, dtype=bool))
            for i in rows:
                self._end_trial(i)
        super().reset(n_envs, mask)

    def end_episodes(self, mask) -> None:
        """The episodes of the envs where ``mask`` is True have ended: until their next ``episode_start``, calls
        for them (a batch running on for its other envs, ``vcnc_bench.robust``) are not part of their trial."""
        if self._ended is not None:
            self._ended |= np.asarray(mask, dtype=bool)

    def _end_trial(self, i: int) -> None:
        """Turn env i's finished trial into the learned input of its next one (eqs. (9)-(11))."""
        T = int(self._t[i])
        self._t[i] = 0
        self._ended[i] = False
        if T == 0:
            return
        w = self._record_w[i, :T]
        e = self._record_e[i, :T]
        dt = self.decision_period
        psi = 1.0 - np.clip(e / self.beta, -1.0, 1.0) / self.alpha
        integral = np.vstack([np.zeros((1, 2)), np.cumsum(e, axis=0)[:-1]]) * dt  # sum_{tau < t} e(tau) T
        derivative = np.diff(e, axis=0, prepend=e[:1]) / dt  # (e(t) - e(t-1)) / T, 0 at t = 0
        learned = w + psi * (self.k_pl * e + self.k_il * integral + self.k_dl * derivative)
        self._learned[i, :T] = self.q * self._low_pass(learned)
        self._learned_len[i] = T
        self.trials_done[i] += 1

    def _low_pass(self, x: np.ndarray) -> np.ndarray:
        """The optional zero-phase low-pass part of Q (``q_cutoff``) along a trial, (T, 2)."""
        if self.q_cutoff is None or x.shape[0] < 2:
            return x
        from scipy.signal import butter, sosfiltfilt

        sos = butter(2, self.q_cutoff, fs=1.0 / self.decision_period, output="sos")
        return sosfiltfilt(sos, x, axis=0, padlen=min(x.shape[0] - 1, 3 * (2 * len(sos) + 1)))

    def _grow(self) -> None:
        cap = 2 * self._record_w.shape[1]
        for name in ("_record_w", "_record_e", "_learned"):
            old = getattr(self, name)
            new = np.zeros((old.shape[0], cap, 2))
            new[:, : old.shape[1]] = old
            setattr(self, name, new)

    # -- analysis ---------------------------------------------------------------------
    def learning_gain(self, frequencies) -> np.ndarray:
        """``|Q S_i (1 - G L)|`` at ``frequencies`` (Hz): how much of the normal error's content there remains
        after one trial, for the linear loop (psi = 1, no saturation or friction).

        G(z) = T^2 (z + 1) / (2 (z - 1)^2) is the sampled double integrator that
        eq. (5) leaves; the loop gain of eq. (7) broken at the input is
        k_P G(z) + k_D T / (z - 1) (position and velocity fed back, normal-direction
        gains); L(z) = k_PL + k_IL T z^-1 / (1 - z^-1) + k_DL (1 - z^-1) / T; Q as
        the ``q`` and ``q_cutoff`` of the policy.  Where it is below 1 the error
        content falls from trial to trial; where above, it grows.
        """
        f = np.asarray(frequencies, dtype=np.float64)
        T = self.decision_period
        z = np.exp(2j * np.pi * f * T)
        g = T * T * (z + 1.0) / (2.0 * (z - 1.0) ** 2)
        loop = self.k_p[1] * g + self.k_d[1] * T / (z - 1.0)
        zi = 1.0 / z
        learn = self.k_pl + self.k_il * T * zi / (1.0 - zi) + self.k_dl * (1.0 - zi) / T
        q = self.q if self.q_cutoff is None else self.q / (1.0 + (f / self.q_cutoff) ** 4)
        return np.abs(q * (1.0 - g * learn) / (1.0 + loop))

    # -- the command ----------------------------------------------------------------
    def normal_error_vector(self, theta, e_w) -> np.ndarray:
        """e_vn = N N^T e_w (eq. (8) with its sign corrected), mm, (n, 2); N = (-sin, cos) theta."""
        n = np.column_stack([-np.sin(theta), np.cos(theta)])
        return n * np.einsum("ij,ij->i", n, e_w)[:, None]

    def _command(self, obs):
        fb, theta = self._feedback(obs)
        e_w = self.layout.tracking_error(obs)
        rows = np.arange(obs.shape[0])
        t = self._t
        if int(t.max()) >= self._record_w.shape[1]:
            self._grow()
        a_d = self.layout.reference_acceleration(obs)
        known = t < self._learned_len
        w = fb  # a fresh array: the learned input is added in place
        w[known] += self._learned[rows[known], t[known]]
        velocity = self.layout.velocity(obs)
        current = self.linearising_current(a_d + w, velocity)
        live = ~self._ended
        self._record_w[rows[live], t[live]] = (self.applied_acceleration(current, velocity) - a_d)[live]
        self._record_e[rows[live], t[live]] = self.normal_error_vector(theta, e_w)[live]
        self._t[live] += 1
        return current


def run_trials(policy, env, n_trials: int, seed: int | None = 0, *, on_trial=None) -> list:
    """Run ``n_trials`` episodes of ``policy`` on ``env`` in a row, each one an ILC trial.

    Parameters
    ----------
    policy : ILCPolicy or any SB3-style policy
        Called through :func:`vcnc_gym.evaluation.run_episode`, which marks
        each episode's start; an :class:`ILCPolicy` learns from one to the next.
    env : gymnasium.Env
        A vcnc_gym contouring env.
    n_trials : int
        K >= 1.
    seed : int or None
        Passed to every ``env.reset`` (the same plant in every trial).
    on_trial : callable, optional
        Called with (trial number from 1, EpisodeResult) after each trial.

    Returns
    -------
    list of vcnc_gym.evaluation.EpisodeResult
        Trial 1 first.
    """
    from vcnc_gym.evaluation import run_episode
    from vcnc_gym.validation import integer

    n_trials = integer("n_trials", n_trials, 1)
    results = []
    for j in range(n_trials):
        results.append(run_episode(policy, env, seed=seed))
        if on_trial is not None:
            on_trial(j + 1, results[-1])
    return results

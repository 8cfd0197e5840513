"""Predictive controllers on the plant's nominal linear model, reading the reference ahead.

- :mod:`~vcnc_baselines.predictive.design`: the axis model discretised at the control period, the state estimator,
  and the discrete LQ preview gains (Tomizuka and Whitney 1975; Katayama et al. 1985's integral action);
- :mod:`.lq_preview`: the unconstrained optimal preview servo as a policy (``lq-preview``), compiled;
- :mod:`.mpc`: the constrained model predictive controller on the same model, cost and preview (``mpc``).
"""

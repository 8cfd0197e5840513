"""Learning controllers: the command improves from trial to trial.

- :mod:`.ilc`: Simba et al.'s iterative learning control, eqs. (8)-(11).

A new learning controller is one module here plus a line in :mod:`vcnc_baselines.registry`.
"""

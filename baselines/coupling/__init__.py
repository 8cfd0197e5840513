"""Contouring (coupled) controllers: the axes act together on the contour error.

- :mod:`.contouring_fb`: Simba et al.'s contouring feedback, eq. (7);
- :mod:`.ccc`: Koren (1980)'s cross-coupled controller and Koren and Lo (1991)'s variable-gain CCC, with or
  without model-based feedforward.

A new coupling controller is one module here plus a line in :mod:`vcnc_baselines.registry`.
"""

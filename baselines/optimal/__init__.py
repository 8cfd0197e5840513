"""Optimal-control floors: non-causal, never counted as controllers.

- :mod:`.oracle`: per env and per plant instance, the best causal controller on that exact plant plus an input
  correction at every step, optimised offline with the exact plant and the whole reference, replayed;
- :mod:`.search`: the solve (warm starts, inverse-model learning, cross-entropy search);
- :mod:`.rollout`: whole episodes of N candidates in one numba call of the env's step kernel;
- :mod:`.open_loop`: a recorded command sequence as a compiled controller;
- :mod:`.solutions`: the cache of solutions (``solutions/``, shipped for the nominal plants).
"""

"""Optimal-control floors: non-causal, never counted as controllers.

- :mod:`.oracle`: per env and per plant instance, the input found offline with perfect knowledge of that
  plant and of the whole reference (model-inversion ILC run to convergence on the exact plant).
"""

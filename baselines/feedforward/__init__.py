"""Model-based feedforward: the plant's nominal inverse dynamics applied to the reference ahead.

- :mod:`.tables`: the feedforward tables computed once from the env's reference (the CNC interpolator's
  output, known ahead of the servo loop) and the plant's declared nominal inverse dynamics;
- :mod:`.ff_pid`: inverse-model feedforward with friction and backlash pre-compensation plus PID;
- :mod:`.zpetc`: Tomizuka (1987)'s zero-phase-error tracking controller of the discretised closed loop.

A new feedforward controller is one module here plus a line in :mod:`vcnc_baselines.registry`.
"""

"""The papers' report tables, computed beside the benchmark.

- :mod:`.yadav2020`: Yadav, Pathak and Gaur (2020)'s Kharitonov margins and Table 2 step metrics;
- :mod:`.simba`: Simba et al.'s cycle times of their test path, sharp and smoothed;
- :mod:`.circle`: Purtojo et al.'s circle figures (radial error, layout of the circle env);
- :mod:`.feed_override`: the front of max contour error against cycle time (the look-ahead, the operator's
  override, the override agent, the contouring MPC).
"""

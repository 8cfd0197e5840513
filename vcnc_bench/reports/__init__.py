"""The papers' report tables, computed beside the benchmark.

- :mod:`.yadav2020`: Yadav, Pathak and Gaur (2020)'s Kharitonov margins and Table 2 step metrics;
- :mod:`.simba`: Simba et al.'s cycle times of their test path, sharp and smoothed;
- :mod:`.circle`: Purtojo et al.'s circle figures (radial error, layout of the circle env).

The studies' analyses (the feed-override front, the tolerance task's searches) are not installed: they are in the
repository's ``experiments/`` (``docs/studies.md``).
"""

"""The suite's own policy kinds (:class:`vcnc_bench.policies.PolicyKind`), found through the entry points of
``pyproject.toml`` as another package's would be: ``baseline`` (the classical controllers, :mod:`.baseline`) and
``ppo`` (trained agents, :mod:`.ppo`)."""

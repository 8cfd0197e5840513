"""The ``bc`` policy kind of vcnc-bench: a behaviour-cloning policy fitted to a Minari dataset.

Found by the bench through the entry point ``bc`` of the group ``vcnc_bench.policy_kinds`` (``pyproject.toml``).
``bc:PATH`` is the data-only ``.npz`` of :mod:`vcnc_agents.behaviour_cloning` (``vcnc-datasets`` writes the datasets,
``python -m vcnc_agents.behaviour_cloning DATASET_ID --out FILE`` fits one); the env it runs on must be the dataset's (its signature is checked).
It has no default: nothing is shipped.
"""

from __future__ import annotations

from vcnc_agents.behaviour_cloning import load_bc  # an install without the agents extra skips this kind

from ..policies import PolicyKind

__all__ = ["KIND"]


def _make(path: str, env):
    if not path:
        raise ValueError("policy 'bc' needs the file: bc:PATH (a behaviour-cloning .npz)")
    return load_bc(path, env)


KIND = PolicyKind(
    name="bc",
    make=_make,
    description="a behaviour-cloning policy fitted to a vcnc-datasets dataset: bc:FILE.npz",
)

"""vcnc-bench: the layer above ``vcnc_gym``, ``vcnc_baselines`` and ``vcnc_agents`` that runs them all.

``vcnc-bench`` (:func:`vcnc_bench.cli.main`) runs every policy on every env
and prints one table; :mod:`vcnc_bench.policies` turns specs into policies
through the kinds found through entry points (the suite's own in
:mod:`vcnc_bench.kinds`); :mod:`vcnc_bench.papers` holds the papers' figures.

The command line (:mod:`vcnc_bench.cli`, which draws plots and runs the robust evaluation) is imported only when
``main`` or ``format_table`` is first used, so a package that declares a policy kind
(``from vcnc_bench.policies import PolicyKind``) does not import it.
"""

from .papers import PAPER_TABLE_4, paper_figures
from .policies import (
    POLICY_KINDS,
    PolicyKind,
    check_policy_spec,
    default_specs,
    policy_kinds,
    policy_label,
    register_policy_kind,
    resolve_policy,
)

__all__ = [
    "main",
    "format_table",
    "PAPER_TABLE_4",
    "paper_figures",
    "PolicyKind",
    "POLICY_KINDS",
    "register_policy_kind",
    "policy_kinds",
    "policy_label",
    "check_policy_spec",
    "resolve_policy",
    "default_specs",
]


def __getattr__(name: str):
    if name in ("main", "format_table"):
        from . import cli

        return getattr(cli, name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")

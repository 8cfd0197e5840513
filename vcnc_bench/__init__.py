"""vcnc-bench: the layer above ``vcnc_gym``, ``baselines`` and ``agents`` that runs them all.

``vcnc-bench`` (:func:`vcnc_bench.cli.main`) runs every policy on every env
and prints one table; :mod:`vcnc_bench.policies` turns specs into policies
through the kinds the other packages register; :mod:`vcnc_bench.papers`
holds the papers' figures.
"""

from .cli import format_table, main
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

__all__ = ["main", "format_table", "PAPER_TABLE_4", "paper_figures", "PolicyKind", "POLICY_KINDS",
           "register_policy_kind", "policy_kinds", "policy_label", "check_policy_spec", "resolve_policy",
           "default_specs"]

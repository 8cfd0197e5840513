"""Policy kinds: how the bench turns a spec ("qft", "ppo:runs/x/best") into a policy.

The bench names no controller and no agent format itself.  A package that
provides policies registers a :class:`PolicyKind`, either by calling
:func:`register_policy_kind` or, to be found without being imported first,
through the entry-point group ``vcnc_bench.policy_kinds`` of its
distribution (``pyproject.toml``)::

    [project.entry-points."vcnc_bench.policy_kinds"]
    baseline = "vcnc_bench.kinds.baseline:KIND"
    ppo = "vcnc_bench.kinds.ppo:KIND"

A spec is ``KIND:ARGUMENT`` (``baseline:qft``, ``ppo:PATH``) or a bare name:
a name one kind answers to (``qft``, from ``PolicyKind.names``) or a kind
with its default argument (``ppo``: the agent shipped for the env).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from importlib import metadata
from pathlib import Path
from typing import Any, Callable

__all__ = [
    "BenchContext",
    "PolicyKind",
    "POLICY_KINDS",
    "register_policy_kind",
    "policy_kinds",
    "split_spec",
    "policy_label",
    "check_policy_spec",
    "expand_spec",
    "resolve_policy",
    "default_specs",
    "policy_choices",
]

ENTRY_POINT_GROUP = "vcnc_bench.policy_kinds"


@dataclass
class BenchContext:
    """What a bench run did, for the kinds' reports.

    Attributes
    ----------
    env_ids : list of str
        The envs run, in order; ``envs`` maps them to the env objects.
    results : dict
        ``results[env_id][label]``: the policy's (last) EpisodeResult.
    trials_of : dict
        ``trials_of[(env_id, label)]``: every trial's EpisodeResult of a
        policy that learns across episodes.
    records : list of dict
        The JSON records (every trial).
    plots : Path or None
        Where plots go (``--plots``); a report that draws one appends its
        path to ``plots_written``.
    trials : int
        ``--trials``.
    shown : dict
        ``shown[env_id]``: the policy labels that env's plots show (:func:`vcnc_bench.plots.shown_labels`); a
        report that draws a plot of its own shows those.
    prepared : dict
        ``prepared[env_id][kind]``: what that kind's :attr:`PolicyKind.prepare` gave for the env (computed where
        the env ran, a worker process, while the others ran).
    """

    env_ids: list
    envs: dict
    plots: Path | None = None
    trials: int = 1
    results: dict = field(default_factory=dict)
    trials_of: dict = field(default_factory=dict)
    records: list = field(default_factory=list)
    plots_written: list = field(default_factory=list)
    shown: dict = field(default_factory=dict)
    prepared: dict = field(default_factory=dict)

    def shown_results(self, env_id: str) -> dict:
        """{label: EpisodeResult} of the runs on ``env_id`` its plots show (all of them if none was chosen)."""
        results = self.results.get(env_id, {})
        labels = self.shown.get(env_id)
        return dict(results) if labels is None else {k: v for k, v in results.items() if k in labels}


@dataclass(frozen=True)
class PolicyKind:
    """One kind of policy the bench can build.

    Attributes
    ----------
    name : str
        The KIND of a ``KIND:ARGUMENT`` spec.
    make : callable (argument: str, env) -> policy
        Builds a policy with SB3's ``predict`` for ``env``; ValueError or
        OSError for a bad argument.
    names : callable () -> list of str
        Bare names this kind answers to (a baseline's name); default none.
    defaults : callable (env) -> list of str
        The specs of this kind the bench runs on ``env`` when no
        ``--policy`` is given: those that apply to its plant; default none.
    extras : callable (env) -> list of str
        Specs that apply to ``env`` but run only with ``vcnc-bench --all``
        (or when named): those whose episode costs minutes; default none.
    report : callable (BenchContext) -> list of str, optional
        Extra report lines printed under the table (a stability check, a
        paper's table in its own shape); it may draw plots into
        ``context.plots``.
    prepare : callable (env) -> object, optional
        A report's work on one env that does not depend on the runs (a
        paper's table over plants of its own): run where the env runs, in
        a worker process alongside the others, and handed to ``report`` as
        ``context.prepared[env_id][name]`` (picklable; None: nothing).
    description : str
        One line for ``--help``.
    expand : callable (argument: str) -> list of str, optional
        The arguments one argument stands for, each run as a policy of its own and judged together (a folder of
        training seeds: each seed's agent); None, or a list of the argument alone: itself.
    """

    name: str
    make: Callable[[str, Any], Any]
    names: Callable[[], list] = field(default=lambda: [])
    defaults: Callable[[Any], list] = field(default=lambda env: [])
    extras: Callable[[Any], list] = field(default=lambda env: [])
    report: Callable | None = None
    prepare: Callable | None = None
    description: str = ""
    expand: Callable[[str], list] | None = None


#: Kind name -> PolicyKind: those registered, and those of the entry points once loaded.
POLICY_KINDS: dict[str, PolicyKind] = {}
_loaded = False


def register_policy_kind(kind: PolicyKind) -> PolicyKind:
    """Add (or replace) a policy kind; returns it."""
    if not isinstance(kind, PolicyKind):
        raise ValueError(f"expected a PolicyKind, got {kind!r}")
    POLICY_KINDS[kind.name] = kind
    return kind


def policy_kinds() -> dict[str, PolicyKind]:
    """Every policy kind: the registered ones and those of installed entry points (loaded once).

    An entry point whose package cannot be imported (e.g. the agents extra is
    not installed) is skipped: its kind is simply not offered.
    """
    global _loaded
    if not _loaded:
        _loaded = True
        for ep in metadata.entry_points(group=ENTRY_POINT_GROUP):
            if ep.name in POLICY_KINDS:
                continue
            try:
                kind = ep.load()
            except ImportError:
                continue
            register_policy_kind(kind)
    return POLICY_KINDS


def _bare_names() -> dict[str, str]:
    """Bare name -> kind name, for the names kinds answer to."""
    out = {}
    for kind in policy_kinds().values():
        for n in kind.names():
            out.setdefault(n, kind.name)
    return out


def split_spec(spec: str) -> tuple[str, str]:
    """(kind, argument) of a spec; a bare name maps to the kind that answers to it."""
    kind, sep, arg = spec.partition(":")
    if sep:
        return kind, arg
    bare = _bare_names()
    if spec in bare:
        return bare[spec], spec
    return spec, ""


def expand_spec(spec: str) -> list[str]:
    """The specs ``spec`` stands for: its kind's :attr:`PolicyKind.expand` of its argument (``ppo:FOLDER`` of
    training seeds: one ``ppo:`` spec per seed's agent), else ``[spec]``.  ValueError from the kind for a bad
    argument."""
    kind, arg = split_spec(spec)
    found = policy_kinds().get(kind)
    if found is None or found.expand is None or not arg:
        return [spec]
    return [f"{kind}:{a}" for a in found.expand(arg)] or [spec]


def policy_label(spec: str) -> str:
    """Label of a spec in the table and the JSON: the name a kind answers to ("qft" for
    "baseline:qft"), the spec itself otherwise ("ppo", "ppo:runs/x/best")."""
    kind, arg = split_spec(spec)
    kinds = policy_kinds()
    return arg if kind in kinds and arg in kinds[kind].names() else spec


def policy_choices() -> str:
    """The valid specs, for error messages."""
    names = ", ".join(sorted(_bare_names())) or "(none)"
    kinds = ", ".join(sorted(policy_kinds()))
    return f"{names}; or KIND:ARGUMENT with KIND one of: {kinds}"


def check_policy_spec(spec: str) -> None:
    """Raise ValueError, naming the valid choices, if ``spec`` names no known policy."""
    if not isinstance(spec, str) or not spec:
        raise ValueError(f"a policy spec must be a non-empty string; valid policies are {policy_choices()}")
    kind, arg = split_spec(spec)
    kinds = policy_kinds()
    if kind not in kinds:
        raise ValueError(f"unknown policy {spec!r}; valid policies are {policy_choices()}")
    if ":" in spec and not arg.strip():
        raise ValueError(
            f"policy {spec!r} has nothing after ':' (an unset variable?); give {kind}:ARGUMENT, or "
            f"the bare {kind!r} for its default"
        )
    if ":" in spec and kinds[kind].names() and arg not in kinds[kind].names():
        raise ValueError(f"unknown policy {spec!r}; valid policies are {policy_choices()}")


def resolve_policy(spec: str, env) -> Any:
    """A policy (with SB3's ``predict``) for ``env`` from a spec; ValueError listing valid specs if unknown."""
    check_policy_spec(spec)
    kind, arg = split_spec(spec)
    return policy_kinds()[kind].make(arg, env)


def default_specs(env, extras: bool = False) -> list[str]:
    """The specs run on ``env`` by default: every kind's defaults for it, in kind order; with ``extras`` also
    every kind's extras (``vcnc-bench --all``)."""
    out = []
    for kind in policy_kinds().values():
        out.extend(s for s in kind.defaults(env) if s not in out)
        if extras:
            out.extend(s for s in kind.extras(env) if s not in out)
    return out

"""The envs of a ``vcnc-bench`` table: the default table's ids and an :class:`~vcnc_bench.runner.EnvRecipe` per env.

:data:`DEFAULT_IDS` is the table ``vcnc-bench`` runs with no ``--env``; :func:`env_recipes` turns the command
line's ``--env``, ``--all``, ``--program`` and ``--policy`` into recipes (an env's id, its arguments and the
policies to run on it), :func:`build_envs` builds them here, and :data:`LONGEST_FIRST` is the worker pool's order
when the workers build their own.
"""

from __future__ import annotations

from vcnc_gym.envs import ENV_IDS
from vcnc_gym.envs.registry import LEARNABLE_IDS, LEGACY

from . import programs
from .options import program_tolerance
from .policies import check_policy_spec, expand_spec
from .runner import EnvRecipe

__all__ = ["DEFAULT_IDS", "LEGACY_IDS", "LONGEST_FIRST", "build_envs", "env_kwargs", "env_recipes"]

#: The v0 ids, kept for agents trained on them: benchmarked when named.
LEGACY_IDS = tuple(e.id for e in LEGACY)

#: The default table (``vcnc-bench`` with no ``--env``): the ids that carry a verdict, those with a shipped agent
#: (``agents/trained``) to be set against the strongest causal controller and the floor, and Yadav et al. (2020)'s
#: step response (the fourth paper's reproduction; a second).  Between them they hold every paper's machine, the
#: shop floor and the feed override.  ``--all`` runs every id of ``ENV_IDS``: the papers' tasks without an agent
#: (the S-curve omega, the look-ahead heart), the G-code ids (the ISO 230-4 and NAS 979 test pieces, a part
#: program) and the random contour.  Grouped by machine (Jahanpour et al. (2014)'s drive, Simba et al.'s, Purtojo
#: et al.'s table, Yadav et al. (2020)'s axis); the worker pool takes the longest first.
DEFAULT_IDS = (
    "VCNC-Heart-v1",
    "VCNC-HeartShop-v1",
    "VCNC-OmegaLookahead-v1",
    "VCNC-OmegaLookaheadShop-v1",
    "VCNC-OmegaOverride-v1",
    "VCNC-Corners-v1",
    "VCNC-CornersSmooth-v1",
    "VCNC-CornersSmoothShop-v1",
    "VCNC-Circle-v1",
    "VCNC-CircleShop-v1",
    "VCNC-Step-v0",
)


#: The default table's envs, the longest run first (as measured on 2 cores: the hearts about 45 s each, the corners
#: 35, the S-curve omegas 15, the step response 15 with Yadav et al. (2020)'s Table 2, the circles 10, the
#: override 4): the pool's order when the workers build the envs (:func:`run_cost`), so that no long env starts last
#: while the other core idles.
LONGEST_FIRST = (
    "VCNC-Heart-v1",
    "VCNC-HeartShop-v1",
    "VCNC-CornersSmoothShop-v1",
    "VCNC-CornersSmooth-v1",
    "VCNC-Corners-v1",
    "VCNC-OmegaLookaheadShop-v1",
    "VCNC-Step-v0",
    "VCNC-OmegaLookahead-v1",
    "VCNC-Circle-v1",
    "VCNC-CircleShop-v1",
    "VCNC-OmegaOverride-v1",
)


def env_kwargs(args) -> dict:
    """The arguments every env is made with: ``feedrate``, ``plant`` and ``shop_floor`` when given."""
    kwargs = {} if args.feedrate is None else {"feedrate": args.feedrate}
    if args.plant is not None:
        kwargs["plant"] = args.plant
    if args.shop_floor:
        kwargs["shop_floor"] = True
    return kwargs


def unique(items) -> list:
    """``items`` once each, in the order they first come."""
    return list(dict.fromkeys(items))


def _env_ids(args, parser) -> list[str]:
    """The ids run: those named (a v0 or a learnable id too), else every id (``--all``) or :data:`DEFAULT_IDS` (none
    with only ``--program``)."""
    if args.env:
        env_ids = unique(args.env)
    elif args.program:
        env_ids = []
    else:
        env_ids = list(ENV_IDS if args.all else DEFAULT_IDS)
    unknown = [e for e in env_ids if e not in ENV_IDS + LEGACY_IDS + LEARNABLE_IDS]
    if unknown:
        parser.error(
            f"unknown env id(s) {', '.join(map(repr, unknown))}; valid ids are {', '.join(ENV_IDS)} and the "
            f"learnable {', '.join(LEARNABLE_IDS)}"
        )
    return env_ids


def env_recipes(args, parser) -> list[EnvRecipe]:
    """One :class:`~vcnc_bench.runner.EnvRecipe` per env of the table: its id and arguments, the policies named by
    ``--policy`` (none: the defaults of every kind; those that learn across episodes and the kinds' extras only
    with ``--all``)."""
    for spec in unique(args.policy or []):
        try:
            check_policy_spec(spec)
        except ValueError as exc:
            parser.error(str(exc))
    try:
        specs = tuple(unique(m for spec in args.policy or [] for m in expand_spec(spec)))
    except (ValueError, OSError, KeyError) as exc:
        parser.error(f"--policy: {exc}")
    everything = bool(args.all)
    kwargs = env_kwargs(args)
    recipes = [EnvRecipe(e, e, kwargs, specs, everything) for e in _env_ids(args, parser)]
    if args.program:
        try:
            tolerance = program_tolerance(args.tolerance)
            pieces = programs.expand_programs(args.program, args.circle)
        except ValueError as exc:
            parser.error(str(exc))
        recipes += [
            EnvRecipe(key, env_id, kw, specs, everything)
            for key, env_id, kw in programs.program_recipes(
                pieces, tolerance, plant=args.plant, shop_floor=args.shop_floor
            )
        ]
    return recipes


def build_envs(recipes: list[EnvRecipe], parser, built: dict | None = None) -> dict:
    """{key: env} of the recipes (those in ``built`` taken from it); a bad argument (``--plant``, ``--feedrate``, a
    program) exits 2 naming the env."""
    envs = {}
    for r in recipes:
        if built is not None and r.key in built:
            envs[r.key] = built[r.key]
            continue
        try:
            envs[r.key] = r.make()
        except (ValueError, TypeError) as exc:
            parser.error(f"{r.key}: {exc}")
    return envs


def build_quietly(recipes: list[EnvRecipe], built: dict) -> None:
    """Build the recipes' envs into ``built``, stopping at the first that fails (:func:`build_envs` then says
    why, if the workers did not)."""
    for r in recipes:
        try:
            built[r.key] = r.make()
        except Exception:  # noqa: BLE001  (reported by build_envs on the main thread)
            return


def run_cost(envs: dict | None):
    """A recipe's run time estimate for the pool's order: its episode steps; without the envs, the default table's
    measured order (:data:`LONGEST_FIRST`), an env outside it first."""
    if envs is None:
        return lambda r: float(-LONGEST_FIRST.index(r.key)) if r.key in LONGEST_FIRST else 1.0
    return lambda r: float(getattr(envs[r.key].unwrapped, "episode_steps", 0))

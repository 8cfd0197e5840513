"""Baselines by name: ``vcnc_baselines.make("qft", env)``.

The registry maps a name to a policy class; :func:`make` builds it for an env
from ``env.unwrapped`` (observation layout, decision period, nominal plant)
and the keyword parameters, whose defaults are the paper's values.

The causal controllers are listed here (:data:`CONTROLLERS`).  A non-causal
floor is built from them (the oracle starts from every causal controller), so
it stands above this module and registers itself (:func:`register_floor`,
``vcnc_baselines.optimal.oracle``, imported by ``baselines``).
"""

from __future__ import annotations

import inspect

from .base import BaselinePolicy
from .coupling.ccc import CrossCoupledPolicy, FeedforwardCrossCoupledPolicy
from .coupling.contouring_fb import ContouringFBPolicy
from .feedforward.ff_pid import FeedforwardPIDPolicy
from .feedforward.online import OnlineFeedforwardPIDPolicy
from .feedforward.zpetc import ZPETCPolicy
from .feedback.fuzzy import FuzzyPolicy
from .feedback.nctf import NCTFPolicy
from .feedback.pd_ref import ReferencePDPolicy
from .feedback.pi_imc_hinf_policies import HinfPolicy, HinfReducedPolicy, IMCPolicy, PIPolicy
from .feedback.qft import QFTPolicy
from .feedback.smc import SlidingModePolicy
from .learning.ilc import ILCPolicy
from .predictive.lq_preview import LQPreviewPolicy
from .predictive.mpc import MPCPolicy
from .predictive.mpcc import MPCCPolicy

__all__ = [
    "make",
    "names",
    "policy_class",
    "in_default_table",
    "register_floor",
    "CONTROLLERS",
    "FLOORS",
    "REGISTRY",
    "VARIANTS",
    "EXTRA_VARIANTS",
]

#: The causal controllers, by family (each class names itself: its ``name`` attribute is its registry key).
CONTROLLERS: tuple[type[BaselinePolicy], ...] = (
    # feedback
    QFTPolicy,  # Jahanpour et al. (2014), section 2c
    SlidingModePolicy,  # Altintas, Erkorkmaz and Zhu (2000), Jahanpour et al.'s Table 2
    FuzzyPolicy,  # Jahanpour et al.'s Table 1
    PIPolicy,  # Yadav, Pathak and Gaur (2020), section 3.2
    IMCPolicy,  # their eq. (23)
    HinfPolicy,  # their eq. (28)
    HinfReducedPolicy,  # their eq. (29)
    NCTFPolicy,  # Purtojo et al., Fig. 1(a), Table I, eqs. (1)-(2)
    ReferencePDPolicy,  # the normalised score's 0: PD by pole placement at a fixed fraction of servo_bandwidth
    # feedforward
    FeedforwardPIDPolicy,  # inverse-model feedforward + PID, every plant
    ZPETCPolicy,  # Tomizuka (1987), every plant
    OnlineFeedforwardPIDPolicy,  # ff-pid from the observed reference: a feed override's re-timed reference
    # coupling
    ContouringFBPolicy,  # Simba et al., eq. (7)
    CrossCoupledPolicy,  # Koren (1980), every plant
    FeedforwardCrossCoupledPolicy,  # feedforward + Koren and Lo (1991)'s variable-gain CCC
    # learning
    ILCPolicy,  # Simba et al., eqs. (8)-(11)
    # predictive
    LQPreviewPolicy,  # Tomizuka and Whitney (1975), Katayama et al. (1985), every plant
    MPCPolicy,  # the same model, cost and preview with the input limit: a QP per control period (DAQP)
    MPCCPolicy,  # Lam, Manzie and Good (2010, 2013): contouring MPC with its own progress, on feed-override ids
)

#: The non-causal floors (``causal = False``), by name: registered by their modules (:func:`register_floor`).
FLOORS: dict[str, type[BaselinePolicy]] = {}

#: Name -> policy class: the controllers and the floors.
REGISTRY: dict[str, type[BaselinePolicy]] = {cls.name: cls for cls in CONTROLLERS}


def register_floor(cls: type[BaselinePolicy]) -> type[BaselinePolicy]:
    """Register a non-causal floor under its ``name`` (a module above the registry, which builds it from the
    causal controllers); returns the class."""
    if getattr(cls, "causal", True) is not False:
        raise ValueError(f"{cls.__name__} is causal: list it in CONTROLLERS")
    if cls.name in REGISTRY and REGISTRY[cls.name] is not cls:
        raise ValueError(f"baseline name {cls.name!r} is taken by {REGISTRY[cls.name].__name__}")
    FLOORS[cls.name] = REGISTRY[cls.name] = cls
    return cls


#: Name -> (registered class name, parameters it fixes): a controller of the
#: registry with some of its parameters changed, benchmarked under its own name.
VARIANTS: dict[str, tuple[str, dict]] = {
    # QFT's feedback G(s) without the pre-filter (F = 1): isolates the share of
    # the contour error that the paper's F(s) causes (docs/papers/jahanpour2014.md).
    "qft-g": ("qft", {"prefilter": ((1.0,), (1.0,))}),
    # Simba et al.'s ILC with a 20 Hz zero-phase low-pass Q: monotone convergence
    # where Table I's q = 1 lets the ringing above 38.5 Hz grow (baselines/learning/ilc.py).
    "ilc-q": ("ilc", {"q_cutoff": 20.0}),
    # Koren and Lo (1991)'s variable-gain CCC, without feedforward.
    "vgccc": ("ccc", {"variable": True}),
    # The model-based controllers commissioned per machine: an identification run on each plant before its
    # episode (vcnc_baselines.commissioning); the bare names use the nominal machine's shipped record.
    "ff-pid@machine": ("ff-pid", {"commissioning": "machine"}),
    "zpetc@machine": ("zpetc", {"commissioning": "machine"}),
    "ccc@machine": ("ccc", {"commissioning": "machine"}),
    "ff-ccc@machine": ("ff-ccc", {"commissioning": "machine"}),
    # The law that runs under a feed override, commissioned per machine the same way (the dial's opponent on the
    # shop floor and the base of the shop-floor tolerance agents).
    "ff-pid-online@machine": ("ff-pid-online", {"commissioning": "machine"}),
    # The predictive pair on the nominal machine's commissioned (identified) model, with the mode and the command
    # delay where the record has them, at the input weight of the commissioning's margin rule on the LQ loop;
    # the bare names use the plant's declared nominal model (vcnc_baselines.predictive.lq_preview, "The model").
    "lq-preview@commissioned": ("lq-preview", {"model": "commissioned"}),
    "mpc@commissioned": ("mpc", {"model": "commissioned"}),
}

#: Variants vcnc-bench's default table leaves out (run when named, or with ``--all``): the predictive pair on the
#: commissioned model, weaker than the bare names where measured (experiments/classical-opponents/README.md, "Predictive control on
#: the commissioned model"); ``ff-pid-online@machine``, whose place is under a feed override (the bench runs no
#: classical law there: the dial is the tolerance search's, ``experiments/tolerance/override_schedule.py``), and which on a
#: planned reference is ``ff-pid@machine`` without the table's lead terms.
EXTRA_VARIANTS = frozenset({"lq-preview@commissioned", "mpc@commissioned", "ff-pid-online@machine"})

_FROM_ENV = ("layout", "decision_period", "nominal_parameters", "plant", "reference", "dt", "task")


def names() -> list[str]:
    """Registered baseline names (controllers and their variants), sorted."""
    return sorted({**REGISTRY, **VARIANTS})


def policy_class(name: str) -> type[BaselinePolicy]:
    """The class registered under ``name``; ValueError for an unknown name."""
    if not isinstance(name, str) or name not in REGISTRY and name not in VARIANTS:
        raise ValueError(f"unknown baseline {name!r}; known baselines are {names()}")
    return REGISTRY[VARIANTS[name][0]] if name in VARIANTS else REGISTRY[name]


def in_default_table(name: str) -> bool:
    """Whether vcnc-bench's default table runs baseline ``name``: its class says so
    (``BaselinePolicy.in_default_table``) and it is not one of :data:`EXTRA_VARIANTS`."""
    return policy_class(name).in_default_table and name not in EXTRA_VARIANTS


def make(name: str, env, **params) -> BaselinePolicy:
    """Build baseline ``name`` for ``env``.

    Parameters
    ----------
    name : str
        One of :func:`names`: "qft", "smc", "fuzzy" or the variant "qft-g" (QFT with F = 1).
    env : gymnasium.Env or stable_baselines3 VecEnv
        A vcnc_gym contouring env (possibly wrapped; its ``unwrapped``
        supplies ``layout``, ``decision_period`` (s) and
        ``nominal_parameters`` (2, P)), or a VecEnv of them.
    **params
        Constructor parameters of the policy class (e.g. ``lam=150`` for
        "smc"); omitted ones take the paper's values.

    Returns
    -------
    BaselinePolicy
        With SB3's ``predict``.

    Raises
    ------
    ValueError
        For an unknown name, an unknown parameter or a bad parameter value.
    """
    cls = policy_class(name)
    accepted = [p for p in inspect.signature(cls.__init__).parameters if p not in ("self",) + _FROM_ENV]
    unknown = sorted(set(params) - set(accepted))
    if unknown:
        raise ValueError(f"unknown parameter(s) {unknown} for baseline {name!r}; it accepts {accepted}")
    fixed = VARIANTS[name][1] if name in VARIANTS else {}
    clash = sorted(set(fixed) & set(params))
    if clash:
        raise ValueError(f"baseline {name!r} fixes {clash}; use {VARIANTS[name][0]!r} to set them")
    return cls.from_env(env, **fixed, **params)


class _ControlPeriodView:
    """A learnable env's task as a classical controller reads an env: its layout in physical units and a decision
    every control period (the controller runs inside the step, every period)."""

    def __init__(self, task):
        self.task = task
        self.layout = task.physical_layout
        self.decision_period = task.dt
        self.nominal_parameters = task.nominal_parameters
        self.plant = task.plant

    @property
    def unwrapped(self):
        return self


def base_controller(name: str, task, n_envs: int):
    """Classical controller ``name`` for ``task`` as a learnable env's ``base=`` runs it: the policy and its
    compiled form for ``n_envs`` envs (the entry point of ``vcnc_gym.envs.decision.ENTRY_POINT_GROUP``).

    ValueError for an unknown name or a controller without a compiled form."""
    if name not in names():
        raise ValueError(f"base must be one of {names()}, got {name!r}")
    policy = make(name, _ControlPeriodView(task))
    compiled = policy.compiled(n_envs)
    if compiled is None:
        raise ValueError(
            f"base={name!r} has no compiled form to run inside the step; use a controller with one "
            "(ff-pid, zpetc, ccc, ff-ccc, pd-ref, ...)"
        )
    return policy, compiled

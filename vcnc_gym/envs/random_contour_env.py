"""VCNC-RandomContour-v1: a new contour at every reset, drawn from the reset's seed."""

from __future__ import annotations

import math

import numpy as np

from ..gcode import path_limits, read_program
from ..gcode.toolpath import corner_side
from ..gcode.random_contour import RandomContourSpec, random_program, spec_for
from ..plants import get_plant
from ..validation import positive
from .contouring_env import ContouringEnv
from .signatures import forwarded_signature

__all__ = ["RandomContourEnv", "LOOKAHEAD_SPACING", "check_blends_fit"]

#: The look-ahead's curvature sample spacing on random contours, mm: five times the default 0.01 mm (which is
#: 1/19 of the omega's 0.19 mm corners), as the tightest arc here is 2 mm; blends keep >= 8 samples each.
LOOKAHEAD_SPACING = 0.05


def check_blends_fit(spec: RandomContourSpec, tolerance: float, acceleration: float, jerk: float) -> None:
    """ValueError unless every corner blend at ``tolerance`` mm fits in the shortest line of ``spec``.

    A line between two corners gives each blend its side l_s (Simba et al.'s eq. (22),
    :func:`vcnc_gym.gcode.toolpath.corner_side`); the flattest corner (``turn_min``) has the longest, and both
    ends of the turn range are checked.  Checked at construction, so that no reset fails later in a run.
    """
    if spec.line_probability == 0.0 or spec.moves_max < 2:
        return
    turns = {math.ceil(spec.turn_min), math.floor(spec.turn_max)}
    side = max(corner_side(math.radians(t), tolerance, acceleration, jerk) for t in turns)
    if 2.0 * side >= spec.line_min:
        raise ValueError(
            f"tolerance = {tolerance:g} mm is too large for the spec's lines: a corner blend takes "
            f"{side:.4g} mm of each leg, and a line of line_min = {spec.line_min:g} mm between two "
            f"corners needs more than twice that; lower tolerance or raise spec line_min"
        )


class RandomContourEnv(ContouringEnv):
    r"""Contour following on a contour drawn anew at every reset (:mod:`vcnc_gym.gcode.random_contour`).

    Each reset draws a random part program (4 to 8 moves: G01 lines of 5 to
    30 mm with corners of 20 to 120 degrees, G02/G03 arcs of radius 2 to 20
    mm, log-uniform, and sweep 30 to 180 degrees; one feed of 2000 to 6000
    mm/min; the distributions are
    :class:`~vcnc_gym.gcode.random_contour.RandomContourSpec`'s) from the
    env's generator, so ``reset(seed=s)`` gives the same contour for the same
    s, and reads it as ``VCNC-GCode-v1`` does: Simba et al.'s corner blends at
    ``tolerance`` mm, exact arcs, the look-ahead feed within the plant's path
    limits.  The program is in the reset info (``info["program"]``).  The
    plant (nominal, fixed or drawn with ``randomize=True``) is drawn after
    the contour, from the same generator.

    Everything else (observation, action, reward, episode end) is
    :class:`~vcnc_gym.envs.ContouringEnv`'s; the observation space does not
    change from contour to contour (the contours stay within +-240 mm, inside
    the layout's 1000 mm position bound).  ``episode_steps`` follows the
    contour of the current episode.

    ``gym.make_vec("VCNC-RandomContour-v1", num_envs=N)`` is Gymnasium's
    ``SyncVectorEnv``: env i, seeded s + i, draws its own contours.  The
    native vector env shares one contour between its N envs (one packed
    reference and projector grid read by the compiled step); per-env contours
    there would need per-env reference and contour arrays in the kernel.

    ## Arguments

    ``tolerance`` (mm, 0.01), ``spec`` (a RandomContourSpec or a dict of
    its fields; default the plant's entry of
    :attr:`PlantModel.random_contour <vcnc_gym.plants.contract.PlantModel>` over the
    defaults above: Purtojo et al.'s table draws contours a tenth of the size
    at 30-120 mm/min), ``plant`` ("vcnc_feed_drive"), ``acceleration`` /
    ``jerk`` (the path limits, as :class:`~vcnc_gym.envs.gcode_env.GCodeEnv`),
    and every other argument of ContouringEnv but ``contour``, ``feedrate``
    and ``profile``.  The look-ahead samples the curvature every 0.05 mm
    times the spec's smallest radius over the defaults' 2 mm (at most 0.05).

    ## Version History

    - v1: initial release.
    """

    def __init__(
        self,
        tolerance=0.01,
        spec: RandomContourSpec | dict | None = None,
        *,
        plant="vcnc_feed_drive",
        acceleration=None,
        jerk=None,
        render_mode=None,
        **kwargs,
    ):
        for key in ("contour", "feedrate", "profile", "program"):
            if key in kwargs:
                raise ValueError(
                    f"{key}= is drawn at every reset in VCNC-RandomContour-v1; "
                    f"shape the draws with spec= (vcnc_gym.gcode.random_contour.RandomContourSpec)"
                )
        model = get_plant(plant)  # a name or a model; an unknown name is refused here, naming the known ones
        self._spec = spec_for(model, spec)
        # the arcs' scale sets the look-ahead's sampling (0.05 mm for the defaults' 2 mm arcs)
        self._spacing = LOOKAHEAD_SPACING * min(1.0, self._spec.radius_min / RandomContourSpec.radius_min)
        self._limits = path_limits(model, acceleration, jerk)
        self._tolerance = None if tolerance is None else positive("tolerance", tolerance, "mm")
        if self._tolerance is not None:
            check_blends_fit(self._spec, self._tolerance, *self._limits)
        self._kwargs = {"plant": plant, "profile": "lookahead", **kwargs}
        self._render = render_mode
        self.program_text = random_program(np.random.default_rng(0), self._spec)
        super().__init__(render_mode=render_mode, contour=self._toolpath(self.program_text), **self._kwargs)

    def _toolpath(self, text: str):
        a, j = self._limits
        return read_program(text, self._tolerance, acceleration=a, jerk=j, spacing=self._spacing)

    def reset(self, *, seed: int | None = None, options=None):
        """A new contour from the env's generator (seeded by ``seed``), then ContouringEnv's reset."""
        import gymnasium as gym

        gym.Env.reset(self, seed=seed)
        text = random_program(self.np_random, self._spec)
        space = self.observation_space
        spec, rng = self.spec, self._np_random
        ContouringEnv.__init__(self, render_mode=self._render, contour=self._toolpath(text), **self._kwargs)
        self.spec, self._np_random = spec, rng
        if self.observation_space != space:  # the layout's bound: contours beyond ~900 mm
            raise RuntimeError("the drawn contour changed the observation space; narrow the spec's lengths")
        self.observation_space = space
        self.program_text = text
        obs, info = super().reset(seed=None, options=options)
        info["program"] = text
        return obs, info

    def _episode_state(self) -> dict:
        return {**super()._episode_state(), "program_text": self.program_text}

    def _restore_episode(self, state: dict) -> None:
        text = state["program_text"]
        if text != self.program_text:  # the episode's contour, not the constructor's placeholder
            space = self.observation_space
            ContouringEnv.__init__(self, render_mode=self._render, contour=self._toolpath(text), **self._kwargs)
            self.observation_space = space
            self.program_text = text
        super()._restore_episode(state)


RandomContourEnv.__init__.__signature__ = forwarded_signature(
    RandomContourEnv.__init__, ContouringEnv.__init__, drop=("contour", "feedrate", "profile")
)

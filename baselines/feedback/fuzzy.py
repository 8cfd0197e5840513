"""The fuzzy controller (FC) of Jahanpour et al. (2014): Table 1's 7x7 rule base on error and error change.

Jahanpour et al. (2014) give, for both axes, only the rule base (Table 1): seven linguistic
values NL, NM, NS, Z, PS, PM, PL on the error, the error change and the
output, with the output label of rule (error i, change j) equal to the label
index i + j clipped to NL..PL (the Mac Vicar-Whelan table).  Everything else
is chosen here and kept in :data:`DEFAULT_SCALING` and the module constants:

Inference (standard Mamdani, as scikit-fuzzy's ``skfuzzy.control`` does it)
---------------------------------------------------------------------------
* Inputs are normalised, e_n = e / E and de_n = e_dot / D, and clipped to
  [-1, 1] (so NL and PL act as shoulders).
* Seven triangular membership functions per variable, peaks at
  -1, -2/3, ..., 1, half-width 1/3 (neighbours cross at 0.5; memberships sum
  to 1).
* Rule strength = min(mu_e, mu_de) (AND = min); output set clipped at that
  strength (min implication); clipped sets combined by max; crisp output by
  centroid of the aggregated set, computed exactly for the piecewise-linear
  interpolation on a grid of step 1/300 (as ``skfuzzy.defuzz(...,
  'centroid')``).
* The output universe is [-4/3, 4/3] so that the outer sets NL, PL are whole
  triangles whose centroids are -1 and 1: with every rule saturated the
  output reaches exactly +-U.  u = U * centroid, in V.

"Error change" is taken as the error rate e_dot = v_d - v (mm/s) read from
the observation: Delta e per period divided by the period, without
differencing quantised float32 positions.  A per-period change Delta e
corresponds to D * T in mm.

Scalings (:class:`FuzzyScaling`), chosen for this plant, not fitted to the paper
--------------------------------------------------------------------------------
The FC has no integral and no feedforward (the paper's FC has neither), so
the error itself must produce the steady command.  At 100 mm/s (the paper's
feed) the x axis needs c v + T_coul/(K_t K_a), about 0.4 V + 0.7 V = 1.1 V
(Jahanpour et al. (2014), Table 3 friction, nominal B), plus m a, about 1.6 mV per mm/s^2,
on the S-curve ramps and around corners.  Because the table is linear in
i + j and neighbouring sets cross at 0.5, the inference surface is close to
u = U clip(e/E + e_dot/D, -1, 1); with min/max/centroid its slope at the
origin is about 1.5 U/E in e (1.5 U/D in e_dot), falling to about U/E
further out.

* U = 5 V: the output universe is the amplifier range (Table 3), so PL on
  both inputs means full voltage.
* E = 0.05 mm: an error of 50 um commands the full 5 V.  The surface gives
  1 V at about 10 um, so the 1.1 V of steady feed costs about 11 um of
  following error, and the small-signal stiffness (about 150 V/mm) puts the
  loop's natural frequency on the nominal x axis at sqrt(150 / m), about
  300 rad/s, with m = J/(K_t K_a r_g) = 1.6e-3 V s^2/mm.  A tighter E raises
  the stiffness but shrinks the linear region to a few micrometres, where
  the 3 um backlash and the friction jump would make the output switch
  between saturated values.
* D = 10 mm/s: derivative slope about 1.5 U/D = 0.75 V s/mm, so
  2 zeta omega_n = 0.75/m, about 450 1/s, and zeta is about 0.75 at the
  stiffness above: a well-damped loop.  A speed error of 10 mm/s (10 % of
  the feed) saturates the change input.

These values are engineering choices for this plant; the paper's FC errors
(35-44 um, Table 4) were not used to tune them.
"""

from __future__ import annotations

from dataclasses import dataclass, fields

import numpy as np
from numba import njit

from vcnc_gym.validation import positive
from ..base import BaselinePolicy

__all__ = [
    "LABELS",
    "RULE_TABLE",
    "FuzzyScaling",
    "DEFAULT_SCALING",
    "OUTPUT_GRID",
    "FuzzyPolicy",
    "fuzzy_infer",
    "input_memberships",
]

#: Linguistic values, in order of their index -3..3.
LABELS = ("NL", "NM", "NS", "Z", "PS", "PM", "PL")

#: Jahanpour et al. (2014), Table 1: output label; rows error change NL..PL, columns error NL..PL.
_TABLE1 = """
NL NL NL NL NM NS Z
NL NL NL NM NS Z  PS
NL NL NM NS Z  PS PM
NL NM NS Z  PS PM PL
NM NS Z  PS PM PL PL
NS Z  PS PM PL PL PL
Z  PS PM PL PL PL PL
"""
#: Table 1 as label indices 0..6 (NL..PL), ``RULE_TABLE[change, error]``.
RULE_TABLE = np.array([[LABELS.index(t) for t in row.split()] for row in _TABLE1.strip().splitlines()], dtype=np.int64)

#: Peaks of the seven triangular sets on the normalised universes, -1 .. 1.
CENTRES = np.linspace(-1.0, 1.0, 7)
#: Half-width (support radius) of every triangle on the normalised universes.
HALF_WIDTH = 1.0 / 3.0
#: Output universe (normalised): [-4/3, 4/3] in steps of 1/300, so every set is a whole triangle.
OUTPUT_GRID = np.linspace(-4.0 / 3.0, 4.0 / 3.0, 801)


@dataclass(frozen=True)
class FuzzyScaling:
    """Scaling factors of the fuzzy controller (the paper gives none).

    Parameters
    ----------
    error_scale : float
        E in mm: the error at which the error is "large" (NL/PL saturate).
    rate_scale : float
        D in mm/s: the error rate at which the error change is "large".
    output_scale : float
        U in V: the command at the output's PL peak (centroid 1).

    See the module docstring for the reasoning behind the defaults.
    """

    error_scale: float = 0.05
    rate_scale: float = 10.0
    output_scale: float = 5.0


#: The scalings used unless others are given: E = 0.05 mm, D = 10 mm/s, U = 5 V.
DEFAULT_SCALING = FuzzyScaling()


@njit(cache=True)
def input_memberships(x, centres, half_width, out):
    """Triangular memberships of one normalised input x (clipped to [-1, 1]) into ``out`` (7,)."""
    if x < -1.0:
        x = -1.0
    elif x > 1.0:
        x = 1.0
    for k in range(centres.size):
        m = 1.0 - abs(x - centres[k]) / half_width
        out[k] = m if m > 0.0 else 0.0


@njit(cache=True)
def fuzzy_infer(e_n, de_n, rules, centres, half_width, grid, out):
    """Mamdani min/max inference with centroid defuzzification, for a batch.

    Parameters
    ----------
    e_n, de_n : ndarray, (m,)
        Normalised error and error change (clipped to [-1, 1] here).
    rules : ndarray of int, (7, 7)
        Output label index per (change, error), :data:`RULE_TABLE`.
    centres : ndarray, (7,)
        Peaks of the triangular sets on all three normalised universes.
    half_width : float
        Support radius of the triangles.
    grid : ndarray, (G,)
        Increasing output universe on which the centroid is integrated.
    out : ndarray, (m,)
        Normalised crisp outputs, written in place.
    """
    n_sets = centres.size
    mu_e = np.empty(n_sets)
    mu_d = np.empty(n_sets)
    w = np.empty(n_sets)
    active = np.empty(n_sets, dtype=np.int64)  # the output sets with w > 0
    for i in range(e_n.size):
        input_memberships(e_n[i], centres, half_width, mu_e)
        input_memberships(de_n[i], centres, half_width, mu_d)
        for k in range(n_sets):
            w[k] = 0.0
        for j in range(n_sets):
            if mu_d[j] == 0.0:
                continue
            for k in range(n_sets):
                a = min(mu_e[k], mu_d[j])
                o = rules[j, k]
                if a > w[o]:
                    w[o] = a
        # the aggregate is 0 outside the active sets' supports [lo, hi], and a segment between two zeros adds
        # exactly 0 to either sum: integrate from one grid point before the last at or below lo to one after the
        # first at or above hi (the same sums, to the bit, as over the whole grid)
        lo = np.inf
        hi = -np.inf
        n_active = 0
        for o in range(n_sets):
            if w[o] > 0.0:
                lo = min(lo, centres[o] - half_width)
                hi = max(hi, centres[o] + half_width)
                active[n_active] = o
                n_active += 1
        first = max(np.searchsorted(grid, lo, side="right") - 2, 0)
        last = min(np.searchsorted(grid, hi, side="left") + 1, grid.size - 1)
        num = 0.0
        den = 0.0
        x_prev = 0.0
        y_prev = 0.0
        for g in range(first, last + 1):
            x = grid[g]
            y = 0.0
            for a in range(n_active):
                o = active[a]
                t = 1.0 - abs(x - centres[o]) / half_width
                if t > 0.0:
                    v = t if t < w[o] else w[o]
                    if v > y:
                        y = v
            if g > first:
                h = x - x_prev
                den += 0.5 * h * (y_prev + y)
                num += h / 6.0 * (x_prev * (2.0 * y_prev + y) + x * (y_prev + 2.0 * y))
            x_prev = x
            y_prev = y
        out[i] = num / den if den > 0.0 else 0.0


class FuzzyPolicy(BaselinePolicy):
    """Fuzzy PD-type controller of Jahanpour et al. (2014) (Table 1 rules), per axis.

    Parameters
    ----------
    layout : vcnc_gym.envs.layout.ObservationLayout
        Names the observation fields.
    decision_period : float
        Period in s at which :meth:`predict` is called.
    nominal_parameters : array_like, (2, P)
        Nominal plant (only ``u_max``, V, is used: to scale the action).
    error_scale : float
        E in mm, > 0 (default :data:`DEFAULT_SCALING`, 0.05 mm).
    rate_scale : float
        D in mm/s, > 0 (default 10 mm/s).
    output_scale : float
        U in V, > 0 (default 5 V).

    Notes
    -----
    u = U f(e/E, e_dot/D) with e = x_d - x (mm), e_dot = v_d - v (mm/s) and
    f the inference of :func:`fuzzy_infer`; the same rules and scalings on
    both axes.  The controller is memoryless.
    """

    name = "fuzzy"
    plants = ("vcnc_feed_drive",)
    paper = "Jahanpour et al. (2014)"
    state_shape = (0,)

    def __init__(
        self,
        layout,
        decision_period,
        nominal_parameters,
        plant=None,
        error_scale=DEFAULT_SCALING.error_scale,
        rate_scale=DEFAULT_SCALING.rate_scale,
        output_scale=DEFAULT_SCALING.output_scale,
    ):
        super().__init__(layout, decision_period, nominal_parameters, plant)
        self.scaling = FuzzyScaling(
            **{
                f.name: positive(f.name, v)
                for f, v in zip(fields(FuzzyScaling), (error_scale, rate_scale, output_scale))
            }
        )

    def surface(self, e, e_dot) -> np.ndarray:
        """Crisp command in V for errors e (mm) and error rates e_dot (mm/s) of any (equal) shape."""
        e = np.asarray(e, dtype=float)
        e_dot = np.broadcast_to(np.asarray(e_dot, dtype=float), e.shape)
        out = np.empty(e.size)
        s = self.scaling
        fuzzy_infer(
            np.ascontiguousarray(e.ravel() / s.error_scale),
            np.ascontiguousarray(e_dot.ravel() / s.rate_scale),
            RULE_TABLE,
            CENTRES,
            HALF_WIDTH,
            OUTPUT_GRID,
            out,
        )
        return s.output_scale * out.reshape(e.shape)

    def _command(self, obs):
        e = self.layout.tracking_error(obs)
        e_dot = self.layout.reference_velocity(obs) - self.layout.velocity(obs)
        return self.surface(e, e_dot)

"""The commissioning record: what an identification run found on a machine and what the design rules chose.

A :class:`CommissioningRecord` is frozen; it is saved and loaded as JSON (:meth:`~CommissioningRecord.to_json`,
:func:`load`), printed readably (``str(record)``) and plotted (:func:`plot`: the measured frequency response, the
fitted model, the loop with its margins and notch).  It is made three ways (:func:`commission`):

- ``"nominal"``: the identification run on the *nominal* machine of an env, what a machine builder ships with
  every machine of a series.  The records of the suite's machines are shipped as JSON data
  (``baselines/commissioning/shipped/``, rebuilt by ``python -m vcnc_baselines.commissioning.record``), so a run does
  not repeat the experiment; a machine without a shipped record is commissioned when first asked (a few
  seconds) and kept for the process;
- ``"machine"``: an identification run on each plant instance before its episode (commissioning a real machine);
- ``"model"``: the design rules applied to the model its parameters declare, without an experiment (a
  non-causal design when the parameters are a plant's true ones: what the oracle may start from).

In every case the experiment reads only the observation (:mod:`.identify`); the backlash, which the experiment
does not measure, is the nominal model's (the builder's data sheet).
"""

from __future__ import annotations

import dataclasses
import hashlib
import json
import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

import vcnc_gym
from vcnc_gym import schema
from vcnc_gym.envs.drive_servo import machine_key  # a shipped record's file stem (the drives' servos' key)
from vcnc_gym.schema import checked, read_json
from vcnc_gym.validation import flag, positive

from .design import AxisDesign, Margins, design_axis, inverse_dynamics, loop_response
from .identify import AxisModel, Experiment, frf, identify, model_response

__all__ = [
    "CommissioningRecord",
    "commission",
    "make_record",
    "model_record",
    "nominal_record",
    "model_axes",
    "machine_key",
    "experiment_key",
    "ship_machines",
    "ship_nominal",
    "load",
    "check_record",
    "plot",
    "SOURCES",
    "MACHINES_SHIPPED",
    "SHIPPED",
]

#: How a record is made (module docstring).
SOURCES = ("nominal", "machine", "model")
#: Where the shipped records live.
SHIPPED = Path(__file__).with_name("shipped")
_CACHE: dict = {}


@dataclass(frozen=True)
class CommissioningRecord:
    """One machine's commissioning.

    Attributes
    ----------
    plant : str
        The plant's name.
    shop_floor : bool
        The machine is on the shop floor.
    source : str
        One of :data:`SOURCES`.
    dt : float
        Control period, s.
    ceiling : float
        The plant's declared servo bandwidth ceiling, rad/s.
    axes : tuple of AxisModel
        The identified (or declared) model of each axis.
    designs : tuple of AxisDesign
        The design of each axis' loop.
    backlash : tuple of float
        Per axis, mm (the nominal model's).
    friction_time : float
        s, the feedforward's Coulomb transition at a reversal (the plant's declaration).
    identification_s : float
        Wall time of the identification run, s (0 for ``"model"``).
    contour : str
        The contour the experiment's axes followed.
    """

    plant: str
    shop_floor: bool
    source: str
    dt: float
    ceiling: float
    axes: tuple
    designs: tuple
    backlash: tuple
    friction_time: float
    identification_s: float = 0.0
    contour: str = ""

    def inverse(self, with_mode: bool = True):
        """The identified inverse dynamics (:func:`~vcnc_baselines.commissioning.design.inverse_dynamics`)."""
        return inverse_dynamics(self.axes, self.backlash, with_mode=with_mode)

    @property
    def process_force(self) -> np.ndarray:
        """Per axis the identified process force along the path, input unit (2,)."""
        return np.array([a.process_force for a in self.axes])

    def gains(self) -> dict:
        """The servo law's per-axis arrays: ``kp``, ``kd``, ``ki``, ``velocity_filter`` (2,), ``notch`` (2, 5)."""
        d = self.designs
        return {
            "kp": np.array([a.kp for a in d]),
            "kd": np.array([a.kd for a in d]),
            "ki": np.array([a.ki for a in d]),
            "velocity_filter": np.array([a.velocity_pole for a in d]),
            "notch": np.array([a.notch for a in d]),
        }

    # -- JSON -------------------------------------------------------------------
    def to_dict(self) -> dict:
        d = dataclasses.asdict(self)
        return json.loads(json.dumps(d, default=float))

    def to_json(self) -> str:
        return json.dumps(self.to_dict(), indent=1)

    @classmethod
    def from_dict(cls, d: dict, where: str = "the record") -> "CommissioningRecord":
        """The record of ``d`` (:meth:`to_dict`'s mapping), every field checked as :func:`make_record` builds it
        (:func:`check_record`); ValueError naming the field."""
        d = check_record(d, where)
        axes = tuple(AxisModel(**a) for a in d["axes"])
        designs = tuple(AxisDesign(**{**a, "margins": Margins(**a["margins"])}) for a in d["designs"])
        return cls(**{**d, "axes": axes, "designs": designs})

    def save(self, path) -> None:
        Path(path).write_text(self.to_json() + "\n")

    def __str__(self) -> str:
        lines = [
            f"commissioning of {self.plant}{' on the shop floor' if self.shop_floor else ''} ({self.source}; "
            f"dt = {self.dt:g} s; identification {self.identification_s:.1f} s"
            f"{' along ' + self.contour if self.contour else ''})"
        ]
        for name, a, d in zip("xy", self.axes, self.designs):
            mode = (
                f"mode {a.mode_frequency:.1f} Hz, zeta {a.mode_damping:.3f}"
                if a.mode_frequency > 0
                else "no mode found"
            )
            lines.append(
                f"  {name}: m = {a.mass:.4g} /(mm/s^2), c = {a.viscous or a.damping:.3g} /(mm/s), {mode}, "
                f"dead time {1e3 * a.delay:.3f} ms, Coulomb +{a.coulomb[0]:.3f}/{a.coulomb[1]:.3f}, "
                f"process force {a.process_force:.3f}, "
                + (
                    f"Stribeck {a.stribeck[0]:.3g} below {a.stribeck[1]:.3g} mm/s, "
                    if a.stribeck[0] > 0
                    else "no Stribeck curve, "
                )
                + f"velocity noise {a.velocity_noise:.3g} mm/s"
            )
            notch = f"notch {d.notch_frequency:.1f} Hz Q {d.notch_q:g}" if d.notch_frequency > 0 else "no notch"
            vel = f"velocity low-pass {d.velocity_cutoff:.0f} rad/s" if d.velocity_cutoff > 0 else "no velocity filter"
            frac = (
                f" ({d.margins.crossover / (2 * math.pi * a.mode_frequency):.2f} of the mode)"
                if a.mode_frequency > 0
                else ""
            )
            lines.append(
                f"     bandwidth {d.bandwidth:.1f} rad/s, crossover {d.margins.crossover:.1f} rad/s{frac}; "
                f"Kp {d.kp:.4g}, Kd {d.kd:.4g}, Ki {d.ki:.4g}; {vel}; {notch}; margins: GM "
                f"{d.margins.gain_db:.1f} dB, PM {d.margins.phase_deg:.1f} deg, Ms "
                f"{d.margins.sensitivity_db:.2f} dB"
            )
        return "\n".join(lines)


def load(path) -> CommissioningRecord:
    """A record saved by :meth:`CommissioningRecord.save`, checked (:func:`check_record`); a
    :class:`vcnc_gym.schema.BadFile` naming the file and the field if it is not one."""
    with checked(path):
        return CommissioningRecord.from_dict(read_json(path, "a commissioning record"))


#: The axes of a record: the suite's machines are X-Y tables.
AXES = 2


def _pair(name: str, value, rule=schema.number, **kwargs) -> tuple:
    return tuple(rule(f"{name}[{i}]", v, **kwargs) for i, v in enumerate(schema.sequence(name, value, 2)))


def _check_axis(name: str, a) -> dict:
    """One :class:`AxisModel` mapping checked as :func:`~.identify.identify` and :func:`model_axes` build it."""
    fields = [f.name for f in dataclasses.fields(AxisModel)]
    required = ("mass", "damping", "mode_frequency", "mode_damping", "delay", "coulomb", "fit_error", "band")
    a = schema.mapping(name, a, required, known=fields)
    n = schema.number
    out = {
        "mass": positive(f"{name}.mass", a["mass"], "input unit per mm/s^2"),
        "damping": n(f"{name}.damping", a["damping"], "input unit per mm/s"),
        "mode_frequency": n(f"{name}.mode_frequency", a["mode_frequency"], "Hz", minimum=0.0),
        "mode_damping": n(f"{name}.mode_damping", a["mode_damping"], minimum=0.0),
        "delay": n(f"{name}.delay", a["delay"], "s", minimum=0.0),
        "coulomb": _pair(f"{name}.coulomb", a["coulomb"]),
        "fit_error": n(f"{name}.fit_error", a["fit_error"], minimum=0.0),
        "band": _pair(f"{name}.band", a["band"], minimum=0.0),
    }
    for key, unit in (("velocity_noise", "mm/s"), ("dt", "s"), ("viscous", "input unit per mm/s")):
        out[key] = n(f"{name}.{key}", a.get(key, 0.0), unit, minimum=0.0)
    out["process_force"] = n(f"{name}.process_force", a.get("process_force", 0.0))
    out["stribeck"] = _pair(f"{name}.stribeck", a.get("stribeck", (0.0, 0.0)), minimum=0.0)
    return out


def _check_design(name: str, a, dt: float) -> dict:
    """One :class:`AxisDesign` mapping checked as :func:`~.design.design_axis` builds it: positive stiffness,
    non-negative damping and integral gains, a stable velocity pole, a notch below the Nyquist frequency."""
    fields = [f.name for f in dataclasses.fields(AxisDesign)]
    a = schema.mapping(name, a, fields, known=())
    n = schema.number
    out = {
        "bandwidth": positive(f"{name}.bandwidth", a["bandwidth"], "rad/s"),
        "kp": positive(f"{name}.kp", a["kp"], "input unit per mm"),
        "kd": n(f"{name}.kd", a["kd"], "input unit per mm/s", minimum=0.0),
        "ki": n(f"{name}.ki", a["ki"], "input unit per mm s", minimum=0.0),
        "velocity_cutoff": n(f"{name}.velocity_cutoff", a["velocity_cutoff"], "rad/s", minimum=0.0),
        "velocity_pole": n(f"{name}.velocity_pole", a["velocity_pole"], minimum=0.0),
        "notch_frequency": n(f"{name}.notch_frequency", a["notch_frequency"], "Hz", minimum=0.0),
        "notch_q": n(f"{name}.notch_q", a["notch_q"], minimum=0.0),
        "notch": tuple(
            n(f"{name}.notch[{i}]", v) for i, v in enumerate(schema.sequence(f"{name}.notch", a["notch"], 5))
        ),
    }
    if out["velocity_pole"] >= 1.0:
        raise ValueError(f"{name}.velocity_pole must be < 1 (a stable filter pole), got {a['velocity_pole']!r}")
    if out["notch_frequency"] >= 0.5 / dt:
        raise ValueError(
            f"{name}.notch_frequency must be below the Nyquist frequency {0.5 / dt:g} Hz, got {a['notch_frequency']!r}"
        )
    m = schema.mapping(f"{name}.margins", a["margins"], [f.name for f in dataclasses.fields(Margins)], known=())
    out["margins"] = {
        "gain_db": n(f"{name}.margins.gain_db", m["gain_db"], "dB", infinite=True),
        "phase_deg": n(f"{name}.margins.phase_deg", m["phase_deg"], "deg"),
        "sensitivity_db": n(f"{name}.margins.sensitivity_db", m["sensitivity_db"], "dB"),
        "crossover": n(f"{name}.margins.crossover", m["crossover"], "rad/s", minimum=0.0),
    }
    return out


def check_record(d, where: str = "the record") -> dict:
    """``d`` (a :meth:`CommissioningRecord.to_dict` mapping) with every field checked as :func:`make_record` builds
    it, numbers as floats and pairs as tuples: :data:`AXES` axes and designs, a positive control period, bandwidth
    ceiling and stiffness ``kp``, finite numbers; ValueError naming the field otherwise."""
    fields = [f.name for f in dataclasses.fields(CommissioningRecord)]
    d = schema.mapping(where, d, [k for k in fields if k not in ("identification_s", "contour")], known=fields)
    dt = positive("dt", d["dt"], "s")
    axes = schema.sequence("axes", d["axes"], AXES)
    designs = schema.sequence("designs", d["designs"], AXES)
    return {
        "plant": schema.text("plant", d["plant"]),
        "shop_floor": flag("shop_floor", d["shop_floor"]),
        "source": schema.choice("source", d["source"], SOURCES),
        "dt": dt,
        "ceiling": positive("ceiling", d["ceiling"], "rad/s"),
        "axes": tuple(_check_axis(f"axes[{j}]", a) for j, a in enumerate(axes)),
        "designs": tuple(_check_design(f"designs[{j}]", a, dt) for j, a in enumerate(designs)),
        "backlash": tuple(
            schema.number(f"backlash[{j}]", v, "mm", minimum=0.0)
            for j, v in enumerate(schema.sequence("backlash", d["backlash"], AXES))
        ),
        "friction_time": schema.number("friction_time", d["friction_time"], "s", minimum=0.0),
        "identification_s": schema.number("identification_s", d.get("identification_s", 0.0), "s", minimum=0.0),
        "contour": schema.text("contour", d.get("contour", ""), empty=True),
    }


def _ceiling(plant) -> float:
    c = getattr(plant, "servo_bandwidth", None)
    if c is None:
        raise ValueError(
            f"plant {plant.name!r} declares no servo_bandwidth (rad/s): its commissioning has no "
            "ceiling to search below"
        )
    return float(c)


def model_axes(plant, parameters, dt: float) -> list[AxisModel]:
    """The axes as ``parameters`` (2, P) declare them: the inverse dynamics' mass, damping, Coulomb levels and
    dead time, and on the shop floor its mode, delays, sensor and Stribeck curve (no experiment)."""
    inv = plant.inverse(parameters)
    p = np.asarray(parameters, dtype=np.float64)
    names = plant.parameter_names

    def value(name, j, default=0.0):
        return float(p[j, names.index(name)]) if name in names else default

    gain = plant.force_gain(p) if getattr(plant, "force_gain", None) is not None else np.zeros(2)
    axes = []
    for j in range(2):
        stribeck = (float(gain[j]) * value("stribeck_force", j), value("stribeck_velocity", j))
        delays = round(value("command_delay", j)) + round(value("sensor_delay", j))
        q, sigma = value("encoder_resolution", j), value("noise_std", j)
        noise = math.sqrt(2.0 * (sigma**2 + q * q / 12.0)) / dt
        axes.append(
            AxisModel(
                mass=float(inv.mass[j]),
                damping=float(inv.damping[j]),
                mode_frequency=value("mode_frequency", j),
                mode_damping=value("mode_damping", j),
                delay=float(inv.delay[j]) + (delays + 0.5) * dt,
                coulomb=tuple(float(v) for v in inv.coulomb[j]),
                fit_error=0.0,
                band=(0.0, 0.0),
                velocity_noise=noise,
                dt=dt,
                viscous=float(inv.damping[j]),
                stribeck=stribeck if stribeck[0] > 0 else (0.0, 0.0),
            )
        )
    return axes


def _record(task, axes, source, seconds, nominal) -> CommissioningRecord:
    return make_record(task.plant, task.dt, axes, source, nominal, seconds, getattr(task, "contour_name", ""))


def make_record(plant, dt, axes, source, nominal, seconds: float = 0.0, contour: str = "") -> CommissioningRecord:
    """The record of ``axes`` (identified or declared) of ``plant`` at control period ``dt``: the design rules
    applied; the backlash of the ``nominal`` parameters."""
    from vcnc_gym.plants.shop_floor import ShopFloorModel

    ceiling = _ceiling(plant)
    designs = tuple(design_axis(a, dt, a.velocity_noise, ceiling) for a in axes)
    backlash = tuple(float(b) for b in plant.inverse(nominal).backlash)
    return CommissioningRecord(
        plant=plant.name,
        shop_floor=isinstance(plant, ShopFloorModel),
        source=source,
        dt=float(dt),
        ceiling=ceiling,
        axes=tuple(axes),
        designs=designs,
        backlash=backlash,
        friction_time=float(plant.friction_time),
        identification_s=float(seconds),
        contour=contour,
    )


def model_record(plant, parameters, dt: float, nominal=None) -> CommissioningRecord:
    """The ``"model"`` record of ``parameters`` (2, P): the rules applied to the declared model (cached)."""
    nominal = parameters if nominal is None else nominal
    key = ("model", machine_key(plant, parameters, dt), machine_key(plant, nominal, dt))
    if key not in _CACHE:
        _CACHE[key] = make_record(plant, dt, model_axes(plant, parameters, dt), "model", nominal)
    return _CACHE[key]


def nominal_record(plant, nominal, dt: float, task=None) -> CommissioningRecord | None:
    """The ``"nominal"`` record of the machine ``(plant, nominal, dt)``: this process's, else the shipped one,
    else (with ``task``, whose nominal machine it must be) a fresh identification run; None without any."""
    key = machine_key(plant, nominal, dt)
    if key in _CACHE:
        return _CACHE[key]
    path = SHIPPED / f"{key}.json"
    if path.exists():
        _CACHE[key] = load(path)
    elif task is not None:
        models, meas = identify(task, nominal, plant.inverse(nominal))
        _CACHE[key] = _record(task, models[0], "nominal", meas.seconds, nominal)
    else:
        return None
    return _CACHE[key]


def commission(task, source: str = "nominal", parameters=None, experiment: Experiment = Experiment()):
    """The records of ``task``'s machines: one for ``"nominal"`` (the shipped one when there is one), one per
    (2, P) row of ``parameters`` for ``"machine"`` and ``"model"`` (default: the nominal machine)."""
    if source not in SOURCES:
        raise ValueError(f"commissioning must be one of {list(SOURCES)}, got {source!r}")
    nominal = task.nominal_parameters
    if source == "nominal":
        return [nominal_record(task.plant, nominal, task.dt, task)]
    p = np.asarray(nominal if parameters is None else parameters, dtype=np.float64)
    p = p[None] if p.ndim == 2 else p
    if source == "model":
        return [model_record(task.plant, q, task.dt, nominal) for q in p]
    key = experiment_key(task, p, experiment)
    if key not in _MACHINES:  # the same machines: one experiment serves every controller
        records = _load_machines(key)
        if records is None:
            records = _identify_machines(task, p, experiment)
        if len(_MACHINES) >= _MACHINES_KEPT:
            _MACHINES.pop(next(iter(_MACHINES)))
        _MACHINES[key] = records
    return list(_MACHINES[key])


#: Per-machine records of this process, by :func:`experiment_key`: the ``@machine`` variants of one env
#: (``ff-pid@machine``, ``zpetc@machine``, ...) commission its machine once, as a CNC does before it runs any
#: controller on it.
_MACHINES: dict = {}
_MACHINES_KEPT = 8
#: Where the ``"machine"`` records of the default bench's nominal machines are kept (``<experiment_key>.json``):
#: the experiment is deterministic (seeded PRBS and sensor noise), so a stored run is the run; rebuilt by
#: ``python -m vcnc_baselines.commissioning.record --machines ID ...``; ignored with ``VCNC_COMMISSION_RECOMPUTE=1``.
MACHINES_SHIPPED = SHIPPED / "machines"
#: The code an identification run goes through, as (package, file pattern in it): a change to any of it changes
#: every :func:`experiment_key`, so a stored run is never replayed for code that would give another.  Found through
#: the packages, so that a checkout and an installed wheel (where ``baselines/`` is ``vcnc_baselines/``) hash the
#: same files under the same names.
_EXPERIMENT_CODE = (
    ("vcnc_baselines", "commissioning/identify.py"),
    ("vcnc_baselines", "commissioning/design.py"),
    ("vcnc_baselines", "commissioning/record.py"),
    ("vcnc_baselines", "inverse_model.py"),
    ("vcnc_gym", "envs/step_kernel.py"),
    ("vcnc_gym", "envs/task.py"),
    ("vcnc_gym", "plants/**/*.py"),
)


_PACKAGE_ROOTS = {
    "vcnc_baselines": Path(__file__).resolve().parents[1],
    "vcnc_gym": Path(vcnc_gym.__file__).resolve().parent,
}


def _code_digest() -> str:
    global _CODE_DIGEST
    if _CODE_DIGEST is None:
        h = hashlib.sha1()
        for package, pattern in _EXPERIMENT_CODE:
            root = _PACKAGE_ROOTS[package]
            for path in sorted(root.glob(pattern)):
                h.update(f"{package}/{path.relative_to(root).as_posix()}".encode() + b"\0" + path.read_bytes())
        _CODE_DIGEST = h.hexdigest()
    return _CODE_DIGEST


_CODE_DIGEST: str | None = None


def experiment_key(task, parameters, experiment: Experiment = Experiment()) -> str:
    """A digest of everything a ``"machine"`` identification run's records depend on: the plant (name, shop
    floor or not, every machine's parameters (n, 2, P) and the nominal ones), the control period, the reference
    the axes follow, the plant's options, the :class:`Experiment` and the source of the code the run goes
    through (:data:`_EXPERIMENT_CODE`)."""
    from vcnc_gym.plants.shop_floor import ShopFloorModel

    p = np.ascontiguousarray(np.asarray(parameters, dtype=np.float64))
    h = hashlib.sha1()
    h.update(f"{task.plant.name}|{isinstance(task.plant, ShopFloorModel)}|{p.shape}|{experiment!r}|".encode())
    h.update(json.dumps(task.plant_options, sort_keys=True, default=repr).encode())
    for a in (p, task.nominal_parameters, np.float64(task.dt), task.reference_arrays.samples):
        h.update(np.ascontiguousarray(a, dtype=np.float64).tobytes())
    h.update(_code_digest().encode())
    return f"{task.plant.name}-{h.hexdigest()[:16]}"


def _identify_machines(task, parameters, experiment: Experiment) -> list:
    """One identification run on the machines ``parameters`` (n, 2, P) of ``task``, through its step and sensor
    (:func:`~vcnc_baselines.commissioning.identify.identify`): a ``"machine"`` record per machine, each with its share of
    the run's time."""
    nominal = task.nominal_parameters
    models, meas = identify(task, parameters, task.plant.inverse(nominal), experiment)
    return [_record(task, m, "machine", meas.seconds / len(parameters), nominal) for m in models]


def _load_machines(key: str) -> list | None:
    """The stored records of :func:`experiment_key` ``key``, or None (none stored, or recomputation asked)."""
    import os

    path = MACHINES_SHIPPED / f"{key}.json"
    if os.environ.get("VCNC_COMMISSION_RECOMPUTE", "") not in ("", "0") or not path.exists():
        return None
    with checked(path):
        stored = schema.sequence("the file", read_json(path, "a list of commissioning records"), minimum=1)
        return [CommissioningRecord.from_dict(d, f"record [{i}]") for i, d in enumerate(stored)]


def ship_machines(task, experiment: Experiment = Experiment()) -> Path:
    """Run the ``"machine"`` identification of ``task``'s nominal machine afresh and store its records in
    :data:`MACHINES_SHIPPED`; returns the file."""
    key = experiment_key(task, task.nominal_parameters[None], experiment)
    _MACHINES.pop(key, None)
    records = _identify_machines(task, task.nominal_parameters[None], experiment)
    MACHINES_SHIPPED.mkdir(parents=True, exist_ok=True)
    path = MACHINES_SHIPPED / f"{key}.json"
    path.write_text(json.dumps([r.to_dict() for r in records], indent=1) + "\n")
    _MACHINES[key] = records
    return path


def ship_nominal(task) -> CommissioningRecord:
    """Run the ``"nominal"`` identification of ``task``'s nominal machine afresh and (over)write its record in
    :data:`SHIPPED`, the package's data; returns the record.  :func:`nominal_record` reads it (and writes
    nothing)."""
    key = machine_key(task.plant, task.nominal_parameters, task.dt)
    _CACHE.pop(key, None)
    inv = task.plant.inverse(task.nominal_parameters)
    models, meas = identify(task, task.nominal_parameters, inv)
    record = _record(task, models[0], "nominal", meas.seconds, task.nominal_parameters)
    SHIPPED.mkdir(exist_ok=True)
    record.save(SHIPPED / f"{key}.json")
    _CACHE[key] = record
    return record


def plot(record: CommissioningRecord, path, measurement=None, machine: int = 0) -> None:
    """Per axis: the measured frequency response (when ``measurement`` is given) and the fitted model
    (magnitude, phase), and the designed loop's magnitude and phase with its margins and notch."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(2, 2, figsize=(11, 7), sharex="col")
    for j, (a, d) in enumerate(zip(record.axes, record.designs)):
        f = np.logspace(0, np.log10(0.45 / record.dt), 800)
        if measurement is not None:
            fm, G, _ = frf(measurement, machine, j)
            ax[0, j].loglog(fm, np.abs(G), ".", ms=2, color="0.6", label="measured")
            ax[1, j].semilogx(fm, np.degrees(np.angle(G)), ".", ms=2, color="0.6")
        g = model_response(a, f)
        ax[0, j].loglog(f, np.abs(g), label="fitted model")
        ax[1, j].semilogx(f, np.degrees(np.angle(g)))
        w = 2 * np.pi * f
        L = loop_response(a, record.dt, w, d.kp, d.kd, d.ki, d.velocity_pole, d.notch)
        ax[0, j].loglog(f, np.abs(L), label="loop L")
        ax[1, j].semilogx(f, np.degrees(np.angle(L)))
        ax[0, j].axhline(1.0, color="k", lw=0.5)
        if d.notch_frequency > 0:
            ax[0, j].axvline(d.notch_frequency, color="r", ls=":", label=f"notch {d.notch_frequency:.0f} Hz")
        ax[0, j].set_title(
            f"axis {'xy'[j]}: GM {d.margins.gain_db:.1f} dB, PM {d.margins.phase_deg:.0f} deg, "
            f"Ms {d.margins.sensitivity_db:.1f} dB"
        )
        ax[1, j].set_xlabel("frequency, Hz")
        ax[0, j].legend(fontsize=7)
    ax[0, 0].set_ylabel("|G|, mm per input unit; |L|")
    ax[1, 0].set_ylabel("phase, deg")
    fig.suptitle(f"{record.plant}{' (shop floor)' if record.shop_floor else ''}: {record.source} commissioning")
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def _main(argv=None) -> None:
    """Rebuild the shipped records of the suite's contouring envs (``python -m vcnc_baselines.commissioning.record``):
    the nominal records, or with ``--machines`` the ``"machine"`` runs of their nominal machines."""
    import argparse

    import gymnasium as gym

    import vcnc_gym  # noqa: F401  (registers the ids)

    parser = argparse.ArgumentParser(description=_main.__doc__)
    parser.add_argument("env_ids", nargs="+", help="env ids whose nominal machines to commission")
    parser.add_argument(
        "--machines",
        action="store_true",
        help="store the @machine controllers' identification runs (MACHINES_SHIPPED) instead",
    )
    args = parser.parse_args(argv)
    for env_id in args.env_ids:
        env = gym.make(env_id)
        env.reset(seed=0)  # the bench's episode: a random contour is drawn at reset
        task = env.unwrapped.task
        if args.machines:
            print(env_id, "->", ship_machines(task).name, flush=True)
            continue
        record = ship_nominal(task)
        print(env_id, "->", machine_key(task.plant, task.nominal_parameters, task.dt))
        print(record)


if __name__ == "__main__":
    _main()

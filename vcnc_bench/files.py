"""The files ``vcnc-bench`` reads back, checked on load as it writes them (:mod:`vcnc_gym.schema`).

- a bench JSON (``vcnc-bench --json``: the default table's ``{"settings", "plan", "records"}`` or ``--plants``'
  ``{"settings", "robust", "verdicts"}``), read by ``python -m vcnc_bench.check`` and ``python -m
  vcnc_bench.leaderboard``: :func:`read_bench`;
- a leaderboard's rows (the page's ``.json``, ``{"rows": [...]}``), read before a run adds to it: :func:`read_board`.

Each check covers every field the readers use, with the type and range the bench writes (a figure: a finite number
>= 0 or null, never NaN); what is wrong is a :class:`vcnc_gym.schema.BadFile`, one line naming the file and the
field (``board.json: rows[2].max_um must be finite (um), got nan``).
"""

from __future__ import annotations

from vcnc_gym.schema import checked, choice, count, mapping, maybe, number, read_json, sequence, text
from vcnc_gym.validation import flag

__all__ = ["ROLES", "read_bench", "check_bench", "read_board", "check_board", "check_row"]

#: A leaderboard row's role (:mod:`vcnc_bench.leaderboard`).
ROLES = ("floor", "reference", "classical", "learned or yours")
#: A verdict's outcome (:func:`vcnc_bench.verdicts.decide`).
OUTCOMES = ("wins", "ties", "loses")
#: The kinds of plant of a robust record's ``per_plant`` (:class:`vcnc_bench.robust.PlantSet`).
PLANT_KINDS = ("nominal", "sample", "vertex")


def _figure(name: str, value, unit: str = "um"):
    """A figure of the bench: a finite number >= 0, or null (not run, diverged, not finite)."""
    return maybe(number, name, value, unit, minimum=0.0)


def _figures(name: str, value, length: int | None = None) -> list:
    return [_figure(f"{name}[{i}]", v) for i, v in enumerate(sequence(name, value, length))]


def _optional_mapping(name: str, value) -> dict:
    """An object, or null (absent) as an empty one."""
    return {} if value is None else mapping(name, value)


def _optional_text(name: str, value):
    return maybe(text, name, value, empty=True)


def _episode(name: str, r: dict) -> None:
    """A record of the default table: one episode of a policy on an env."""
    mapping(name, r, ("env", "policy", "completed", "diverged"))
    text(f"{name}.env", r["env"])
    text(f"{name}.policy", r["policy"])
    _optional_text(f"{name}.kind", r.get("kind"))
    maybe(count, f"{name}.trial", r.get("trial"), 1)
    flag(f"{name}.completed", r["completed"])
    flag(f"{name}.diverged", r["diverged"])
    for k in ("max_contour_error_um", "mean_contour_error_um", "rms_contour_error_um"):
        _figure(f"{name}.{k}", r.get(k))


def _report_row(name: str, r: dict) -> None:
    """A report's row of the default table (``"table"``: the headroom, ISO 230-4's figures)."""
    text(f"{name}.table", r["table"])
    if r["table"] == "headroom":
        text(f"{name}.env", mapping(name, r, ("env",))["env"])
        maybe(number, f"{name}.headroom", r.get("headroom"), minimum=0.0)


def _table(data: dict) -> None:
    plan = mapping("plan", data.get("plan", {}))
    for env, labels in plan.items():
        for i, label in enumerate(sequence(f"plan[{env!r}]", labels)):
            text(f"plan[{env!r}][{i}]", label)
    for i, r in enumerate(sequence("records", data["records"])):
        mapping(f"records[{i}]", r)
        (_report_row if "table" in r else _episode)(f"records[{i}]", r)


def _verdict(name: str, v) -> None:
    """A robust record's verdict (:meth:`vcnc_bench.verdicts.Verdict.to_dict`)."""
    mapping(name, v, ("outcome", "y", "difference", "low", "high"))
    choice(f"{name}.outcome", v["outcome"], OUTCOMES)
    text(f"{name}.y", v["y"])
    _optional_text(f"{name}.x", v.get("x"))
    for k in ("difference", "low", "high", "iqm_x"):
        maybe(number, f"{name}.{k}", v.get(k))
    if v.get("ci_x") is not None:
        for i, e in enumerate(sequence(f"{name}.ci_x", v["ci_x"], 2)):
            maybe(number, f"{name}.ci_x[{i}]", e)
    count(f"{name}.training_seeds", v.get("training_seeds", 1), 1)


def _per_noise(name: str, p, plants: int) -> None:
    p = mapping(name, p, ("shape", "max_um", "rms_um", "diverged"))
    shape = [count(f"{name}.shape[{i}]", v, 1) for i, v in enumerate(sequence(f"{name}.shape", p["shape"], 2))]
    if shape[1] != plants:
        raise ValueError(f"{name}.shape[1] must be the record's {plants} plants, got {shape[1]}")
    for k in ("max_um", "rms_um"):
        _figures(f"{name}.{k}", p[k], shape[0] * shape[1])
    for i, v in enumerate(sequence(f"{name}.diverged", p["diverged"], shape[0] * shape[1])):
        flag(f"{name}.diverged[{i}]", v)


def _robust_record(name: str, r) -> None:
    """A record of ``--plants``: one policy on one env's plants (:func:`vcnc_bench.robust.summarize`)."""
    required = ("env", "policy", "nominal_completed", "nominal_diverged", "n_samples", "per_plant")
    mapping(name, r, required)
    text(f"{name}.env", r["env"])
    text(f"{name}.policy", r["policy"])
    _optional_text(f"{name}.kind", r.get("kind"))
    _optional_text(f"{name}.group", r.get("group"))
    flag(f"{name}.nominal_completed", r["nominal_completed"])
    flag(f"{name}.nominal_diverged", r["nominal_diverged"])
    count(f"{name}.n_samples", r["n_samples"], 1)
    for k in ("nominal_max_um", "nominal_rms_um"):
        _figure(f"{name}.{k}", r.get(k))
    per = mapping(f"{name}.per_plant", r["per_plant"], ("kind", "max_um", "rms_um", "diverged"))
    kinds = [
        choice(f"{name}.per_plant.kind[{i}]", k, PLANT_KINDS)
        for i, k in enumerate(sequence(f"{name}.per_plant.kind", per["kind"]))
    ]
    if kinds.count("sample") != r["n_samples"]:
        raise ValueError(f"{name}.per_plant.kind must hold n_samples = {r['n_samples']} 'sample' entries")
    for k in ("max_um", "rms_um"):
        _figures(f"{name}.per_plant.{k}", per[k], len(kinds))
    for i, v in enumerate(sequence(f"{name}.per_plant.diverged", per["diverged"], len(kinds))):
        flag(f"{name}.per_plant.diverged[{i}]", v)
    if "per_noise" in r:
        _per_noise(f"{name}.per_noise", r["per_noise"], len(kinds))
    for figure, v in _optional_mapping(f"{name}.verdicts", r.get("verdicts")).items():
        _verdict(f"{name}.verdicts[{figure!r}]", v)


def check_bench(data) -> dict:
    """``data`` if it is a bench JSON as ``vcnc-bench --json`` writes it (the default table's or ``--plants``');
    ValueError naming the first field that is not."""
    mapping("the file", data)
    if "robust" in data:
        mapping("the file", data, ("settings", "robust"))
        for i, r in enumerate(sequence("robust", data["robust"])):
            _robust_record(f"robust[{i}]", r)
    else:
        mapping("the file", data, ("settings", "records"))
        _table(data)
    _settings(mapping("settings", data["settings"]))
    return data


def _settings(s: dict) -> None:
    """The settings a reader uses: the command, the plant, the shop floor and the provenance's CPU and version."""
    _optional_text("settings.command", s.get("command"))
    _optional_text("settings.plant", s.get("plant"))
    flag("settings.shop_floor", s.get("shop_floor", False))
    prov = _optional_mapping("settings.provenance", s.get("provenance"))
    cpu = _optional_mapping("settings.provenance.cpu", prov.get("cpu"))
    _optional_text("settings.provenance.cpu.model", cpu.get("model"))
    libraries = _optional_mapping("settings.provenance.libraries", prov.get("libraries"))
    _optional_text("settings.provenance.libraries['vcnc-gym']", libraries.get("vcnc-gym"))


def read_bench(path) -> dict:
    """The bench JSON ``path``, checked (:func:`check_bench`); :class:`~vcnc_gym.schema.BadFile` naming the file."""
    with checked(path):
        return check_bench(read_json(path, "a vcnc-bench --json output"))


def check_row(name: str, r) -> dict:
    """A leaderboard row (:func:`vcnc_bench.leaderboard.rows_of`) checked; ValueError naming the field."""
    required = ("env", "policy", "max_um", "rms_um", "plants", "iqm_max", "iqm_rms", "verdicts", "role", "source")
    mapping(name, r, required)
    text(f"{name}.env", r["env"])
    text(f"{name}.policy", r["policy"])
    _optional_text(f"{name}.kind", r.get("kind"))
    _figure(f"{name}.max_um", r["max_um"])
    _figure(f"{name}.rms_um", r["rms_um"])
    count(f"{name}.plants", r["plants"], 0)
    maybe(count, f"{name}.seeds", r.get("seeds"), 1)
    for k in ("iqm_max", "iqm_rms"):
        if r[k] is not None:
            for i, v in enumerate(sequence(f"{name}.{k}", r[k], 3)):
                maybe(number, f"{name}.{k}[{i}]", v)
    for k in ("score_max", "score_rms"):
        maybe(number, f"{name}.{k}", r.get(k))
    choice(f"{name}.role", r["role"], ROLES)
    for figure, v in mapping(f"{name}.verdicts", r["verdicts"]).items():
        where = f"{name}.verdicts[{figure!r}]"
        mapping(where, v, ("outcome", "opponent", "difference"))
        text(f"{where}.outcome", v["outcome"])
        text(f"{where}.opponent", v["opponent"])
        for i, e in enumerate(sequence(f"{where}.difference", v["difference"], 3)):
            maybe(number, f"{where}.difference[{i}]", e)
        _optional_text(f"{where}.controller", v.get("controller"))
        count(f"{where}.training_seeds", v.get("training_seeds", 1), 1)
    source = mapping(f"{name}.source", r["source"])
    for k in ("command", "cpu", "version"):
        _optional_text(f"{name}.source.{k}", source.get(k))
    return r


def check_board(data) -> list[dict]:
    """The rows of a leaderboard's ``.json`` (``{"rows": [...]}``), each checked (:func:`check_row`)."""
    rows = sequence("rows", mapping("the file", data, ("rows",))["rows"])
    return [check_row(f"rows[{i}]", r) for i, r in enumerate(rows)]


def read_board(path) -> list[dict]:
    """The rows of the leaderboard's ``.json`` ``path``, checked (:func:`check_board`); BadFile naming the file."""
    with checked(path):
        return check_board(read_json(path, "a leaderboard's rows"))

"""Controller specs: which controllers a replay runs, with which parameters and sweeps.

The command line's three options, parsed here into typed :class:`ControllerSpec` values::

    --controller LAW | NAME=LAW                    a controller (LAW: adaptive, variable-stiffness,
                                                   fixed); NAME defaults to LAW
    --set NAME.[GROUP.]PARAM=VALUE                 one parameter of one controller
    --sweep NAME.[GROUP.]PARAM=START:STOP:COUNT    COUNT evenly spaced values, both ends included
                                                   (COUNT 1 only with START = STOP)
    --sweep NAME.[GROUP.]PARAM=V1,V2,...           the listed values

GROUP is ``cartesian`` (axes x, y, z) or ``joint`` (joint1..joint6); without it a parameter is
set for both groups. PARAM is a field of :class:`~hilrig.control.AdmittanceParams` (SI units:
m in kg, b_d and beta in N*s/m or N*m*s/rad, k_d in N/m or N*m/rad, delta in N or N*m, times in
s) or, with a GROUP, ``preset``. A controller starts from the live loop's presets
(``adaptive`` for the Cartesian group, ``adaptive-joint`` for the joints); presets apply before
the other settings. A controller with several sweeps runs their grid (cartesian product).

The number of runs (each controller's grid: the product of its sweeps' sizes, summed over the
controllers) is computed from the arguments before any value is expanded, and more than
``MAX_RUNS`` is refused at once.

Run names: a controller named explicitly (``soft=adaptive``) keeps its name; one named after
its law gets its settings appended (``adaptive.a1=10``); sweeps append their values to either
(``soft.a1=12.5``).
"""

from __future__ import annotations

import itertools
import math
import re
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, fields

import numpy as np

from hilrig.control import AdmittanceParams, Law, ParameterError, combine, preset
from hilrig.errors import ReplayError

GROUPS = ("cartesian", "joint")
#: The axes of each group, in the order the controller stacks them.
GROUP_AXES: Mapping[str, tuple[str, ...]] = {
    "cartesian": ("x", "y", "z"),
    "joint": ("joint1", "joint2", "joint3", "joint4", "joint5", "joint6"),
}
#: Where every controller starts: the live loop's presets (see hilrig.rig.loop.LoopConfig).
DEFAULT_PRESETS: Mapping[str, str] = {"cartesian": "adaptive", "joint": "adaptive-joint"}
#: The fields a setting may change (``groups`` follows from the input's axes).
PARAMS = tuple(f.name for f in fields(AdmittanceParams) if f.name != "groups")
_NAME = re.compile(r"[A-Za-z0-9_-]+")
#: Most runs one replay may ask for (all controllers and sweep points together).
MAX_RUNS = 10_000

Value = float | bool | str | tuple[float, ...]


@dataclass(frozen=True)
class Setting:
    """One parameter value: ``group`` None means both groups; ``text`` is what the user wrote."""

    param: str
    value: Value
    group: str | None = None
    text: str = ""

    @property
    def key(self) -> str:
        """``param`` or ``group.param``, as written after the controller's name."""
        return self.param if self.group is None else f"{self.group}.{self.param}"

    @property
    def label(self) -> str:
        return f"{self.key}={self.text}"


@dataclass(frozen=True)
class ControllerSpec:
    """One controller run: its run name, law and the parameters of both axis groups.

    ``controller`` is the name it was declared under, ``settings`` every value that differs
    from its starting presets (``--set`` and sweep coordinates), in the order applied.
    """

    name: str
    law: Law
    cartesian: AdmittanceParams
    joint: AdmittanceParams
    controller: str
    settings: tuple[Setting, ...] = ()

    def params_for(self, axis_names: Sequence[str]) -> AdmittanceParams:
        """The combined parameters for an input with ``axis_names`` (one group's axes, in
        order, or both: Cartesian then joints). Raises ReplayError for another axis set."""
        parts: list[tuple[AdmittanceParams, int]] = []
        rest = tuple(axis_names)
        for group in GROUPS:
            axes = GROUP_AXES[group]
            if rest[: len(axes)] == axes:
                parts.append((self.cartesian if group == "cartesian" else self.joint, len(axes)))
                rest = rest[len(axes) :]
        if rest or not parts:
            raise ReplayError(
                f"axes {', '.join(axis_names)} are not x, y, z and/or joint1..joint6 in order"
            )
        try:
            return combine(*parts)
        except ParameterError as err:
            raise ReplayError(f"controller {self.name}: {err}") from err

    @property
    def overrides(self) -> dict[str, Value]:
        """``{key: value}`` of the settings (the last one of a key wins)."""
        return {s.key: s.value for s in self.settings}


def parse_specs(
    controllers: Sequence[str] = (),
    sets: Sequence[str] = (),
    sweeps: Sequence[str] = (),
) -> list[ControllerSpec]:
    """The runs asked for by ``--controller``, ``--set`` and ``--sweep`` arguments (see the
    module docstring); no controller means the three laws. Raises ReplayError, one line
    naming the argument, for anything malformed, unknown or invalid."""
    declared = _declare(controllers or [law.value for law in Law])
    settings: dict[str, list[Setting]] = {name: [] for name in declared}
    for argument in sets:
        name, setting = _setting(argument, "--set", declared)
        settings[name].append(setting)
    asked: dict[str, list[tuple[str, str, str]]] = {name: [] for name in declared}
    for argument in sweeps:
        name, key, text = _assignment(argument, "--sweep", declared)
        asked[name].append((argument, key, text))
    _check_size(asked)
    grids = {name: [_sweep(*sweep) for sweep in asked[name]] for name in declared}
    specs: list[ControllerSpec] = []
    for name, (law, explicit) in declared.items():
        base = name if explicit else name + "".join(f".{s.label}" for s in settings[name])
        for point in itertools.product(*grids[name]):
            run_name = base + "".join(f".{s.label}" for s in point)
            specs.append(_build(run_name, name, law, [*settings[name], *point]))
    return specs  # names are unique: controller names have no '.', sweep values no repeats


def _declare(controllers: Sequence[str]) -> dict[str, tuple[Law, bool]]:
    """``{name: (law, named explicitly)}`` from ``--controller`` arguments, in order."""
    declared: dict[str, tuple[Law, bool]] = {}
    for argument in controllers:
        name, sep, law_text = argument.partition("=")
        if not sep:
            law_text = name
        law = _law(law_text, argument)
        if not _NAME.fullmatch(name):
            raise ReplayError(
                f"--controller {argument}: name {name!r} must be letters, digits, '_' or '-'"
            )
        if name in declared:
            raise ReplayError(f"--controller {argument}: controller {name!r} is declared twice")
        declared[name] = (law, bool(sep))
    return declared


def _law(text: str, argument: str) -> Law:
    try:
        return Law(text)
    except ValueError:
        known = ", ".join(law.value for law in Law)
        raise ReplayError(f"--controller {argument}: law {text!r} is not one of: {known}") from None


def _assignment(argument: str, option: str, declared: Mapping[str, object]) -> tuple[str, str, str]:
    """``NAME.KEY=TEXT`` split into its parts; the controller must be declared."""
    target, sep, text = argument.partition("=")
    name, dot, key = target.partition(".")
    if not (sep and dot and key and text):
        raise ReplayError(f"{option} {argument}: expected NAME.PARAM=VALUE")
    if name not in declared:
        known = ", ".join(declared)
        raise ReplayError(f"{option} {argument}: no controller {name!r} (declared: {known})")
    return name, key, text


def _split_key(argument: str, option: str, key: str) -> tuple[str | None, str]:
    """``param`` or ``group.param`` -> (group or None, param), both checked."""
    group, dot, param = key.rpartition(".")
    if dot and group not in GROUPS:
        raise ReplayError(
            f"{option} {argument}: group {group!r} is not one of: {', '.join(GROUPS)}"
        )
    if param == "preset":
        if not dot:
            raise ReplayError(
                f"{option} {argument}: a preset belongs to one group: "
                "NAME.cartesian.preset=... or NAME.joint.preset=..."
            )
    elif param not in PARAMS:
        raise ReplayError(
            f"{option} {argument}: unknown parameter {param!r}; known: preset, " + ", ".join(PARAMS)
        )
    return (group if dot else None), param


def _setting(argument: str, option: str, declared: Mapping[str, object]) -> tuple[str, Setting]:
    name, key, text = _assignment(argument, option, declared)
    group, param = _split_key(argument, option, key)
    return name, Setting(param, _value(argument, option, group, param, text), group, text)


def _value(argument: str, option: str, group: str | None, param: str, text: str) -> Value:
    """``text`` as a number, a bool, a name, or (with a group) per-axis numbers ``a,b,c``."""
    if "," in text:
        if group is None:
            raise ReplayError(
                f"{option} {argument}: per-axis values need a group (NAME.cartesian.{param}=...)"
            )
        values = tuple(_number(argument, option, part) for part in text.split(","))
        if len(values) != len(GROUP_AXES[group]):
            raise ReplayError(
                f"{option} {argument}: the {group} group has {len(GROUP_AXES[group])} axes, "
                f"got {len(values)} values"
            )
        return values
    lowered = text.lower()
    if lowered in ("true", "false"):
        return lowered == "true"
    try:
        return float(text)
    except ValueError:
        return text  # a name (preset, chi reading, integrator): checked when applied


def _number(argument: str, option: str, text: str) -> float:
    try:
        return float(text)
    except ValueError:
        raise ReplayError(f"{option} {argument}: {text!r} is not a number") from None


def _check_size(asked: Mapping[str, Sequence[tuple[str, str, str]]]) -> None:
    """Refuse more than MAX_RUNS runs, counted from the arguments (nothing expanded)."""
    sizes = {name: [_sweep_size(*sweep) for sweep in sweeps] for name, sweeps in asked.items()}
    total = sum(math.prod(counts) for counts in sizes.values())
    if total > MAX_RUNS:
        grids = "; ".join(
            f"{name}: {' x '.join(map(str, counts))}" for name, counts in sizes.items() if counts
        )
        raise ReplayError(
            f"--sweep: {total} runs ({grids}), more than the limit of {MAX_RUNS}; "
            "sweep fewer values"
        )


def _sweep_size(argument: str, key: str, text: str) -> int:
    """How many values a sweep has, from its text alone."""
    _split_key(argument, "--sweep", key)
    if ":" not in text:
        return text.count(",") + 1
    return _count(argument, text.split(":"))


def _count(argument: str, parts: list[str]) -> int:
    if len(parts) != 3:
        raise ReplayError(f"--sweep {argument}: expected START:STOP:COUNT")
    try:
        count = int(parts[2])
    except ValueError:
        raise ReplayError(f"--sweep {argument}: COUNT {parts[2]!r} is not a whole number") from None
    if count < 1:
        raise ReplayError(f"--sweep {argument}: COUNT must be >= 1")
    return count


def _sweep(argument: str, key: str, text: str) -> list[Setting]:
    """The settings of one sweep: ``START:STOP:COUNT`` or ``V1,V2,...``."""
    group, param = _split_key(argument, "--sweep", key)
    if ":" in text:
        parts = text.split(":")
        count = _count(argument, parts)
        start, stop = (_number(argument, "--sweep", p) for p in parts[:2])
        if not (math.isfinite(start) and math.isfinite(stop)):
            raise ReplayError(f"--sweep {argument}: START and STOP must be finite")
        if count == 1 and start != stop:
            raise ReplayError(
                f"--sweep {argument}: COUNT 1 cannot include both START and STOP; "
                "use COUNT >= 2, or START = STOP for one value"
            )
        # 12 significant digits: the run name shows the value that is used, without 0.1 + 0.2
        # noise (0.30000000000000004)
        texts = [f"{v:.12g}" for v in np.linspace(start, stop, count)]
        values: list[Value] = [float(t) for t in texts]
    else:
        texts = text.split(",")
        values = [_value(argument, "--sweep", None, param, t) for t in texts]
    if len(set(values)) != len(values):
        raise ReplayError(f"--sweep {argument}: values repeat")
    return [Setting(param, v, group, t) for v, t in zip(values, texts, strict=True)]


def _build(name: str, controller: str, law: Law, settings: Sequence[Setting]) -> ControllerSpec:
    """Apply presets, then the other settings, to both groups; validate each group."""
    params = {g: preset(DEFAULT_PRESETS[g]) for g in GROUPS}
    ordered = sorted(settings, key=lambda s: s.param != "preset")  # stable: presets first
    for setting in ordered:
        for group in GROUPS if setting.group is None else (setting.group,):
            params[group] = _apply(name, params[group], setting)
    return ControllerSpec(
        name, law, params["cartesian"], params["joint"], controller, tuple(settings)
    )


def _apply(name: str, params: AdmittanceParams, setting: Setting) -> AdmittanceParams:
    try:
        if setting.param == "preset":
            return preset(str(setting.value))
        return params.with_(**{setting.param: _typed(setting)})
    except ParameterError as err:
        raise ReplayError(f"run {name}: {setting.label}: {err}") from err


def _typed(setting: Setting) -> Value:
    """The value in the field's type: bools and names stay, numbers for numeric fields."""
    value, param = setting.value, setting.param
    flags = ("state_machine", "rate_guard")
    names = ("chi", "beta_reading", "integrator")
    if param in flags and not isinstance(value, bool):
        raise ParameterError(f"{param} takes true or false, not {setting.text!r}")
    if param not in flags and param not in names and isinstance(value, bool | str):
        raise ParameterError(f"{param} takes a number, not {setting.text!r}")
    return value

"""What a sweep draws and how each sample runs: the model swept, defaults, the TOML config file,
validation, and the draws of every sample.

Models (`--model`, or `model = "..."` at the top of the config file; default "shaft"):

- "shaft": BacklashShaft, the paper's rig, under the PI on the motor speed (docs/model.md §3);
- "belt": BacklashBelt, the belt drive, under the same loop;
- "web": BacklashWeb, the belt drive pulling one span of web, under the speed PI and the outer
  tension PI that trims its reference (docs/model.md §8).

Config file (TOML, every entry optional; an entry replaces the default of the same name). The
shaft's, in SI units on the rectilinear rig:

    model = "shaft"               # optional; must agree with --model when both are given

    [parameters]                  # BacklashShaft parameters (docs/model.md §4), SI units
    Delta = { low = 0.5e-3, high = 3e-3 }   # uniform on [low, high]
    k     = { nominal = 200.0, tol = 0.10 } # uniform on nominal * [1 - tol, 1 + tol]
    J_L   = { nominal = 2.55, tol = 0.05 }
    J_m   = 2.28                            # a plain number: fixed in every sample

    [loop]                        # the PI on the motor speed, closed outside the FMU
    Kp = 42.7
    Ki = 179.2

    [reference]                   # w_ref(t) = amplitude * sin(2 pi frequency t)
    amplitude = 0.05
    frequency = 1.41

    [run]
    horizon = 1.5                 # simulated seconds per run
    h = 1e-3                      # communication step [s]
    accuracy = 0.02               # required load-speed accuracy epsilon [m/s]

The belt's (stiffness K_b in N/m, Delta in m on the gears' pitch circle, speeds in rad/s):

    model = "belt"
    [parameters]
    Delta = { low = 25e-6, high = 100e-6 }
    K_b   = { nominal = 2e5, tol = 0.15 }
    J_L   = { nominal = 0.005, tol = 0.05 }
    [run]
    horizon = 0.1
    h = 1e-4
    accuracy = 2.2                # [rad/s]

The web line's (the belt's parameters and the span's R_w, L_w, EA, v_ref; the tension PI's
gains Kp_T, Ki_T in [loop]; the tension set point T_ref in [reference]; the tension accuracy
eps_T in [run], the speed accuracy optional there):

    model = "web"
    [parameters]
    Delta = { low = 25e-6, high = 100e-6 }
    EA    = { nominal = 1e5, tol = 0.10 }
    L_w   = { nominal = 1.0, tol = 0.05 }
    [loop]
    Kp_T = 0.01                   # rad/(s.N)
    Ki_T = 0.05                   # rad/(s2.N)
    [reference]
    amplitude = 30.0              # motor-speed sine [rad/s]
    frequency = 5.0               # [Hz]
    T_ref = 2.0                   # tension set point [N]
    [run]
    horizon = 0.5
    h = 1e-4
    tension_accuracy = 20.0       # required tension accuracy eps_T [N]
    accuracy = 3.0                # optional: required load-speed accuracy [rad/s]

Parameters of each model (PARAMETERS_OF; also the order of the draws and of the table's
columns): shaft J_m, J_L, b_m, b_L, k, Delta; belt J_m, J_L, b_m, b_L, K_b, R_1, R_2, R_g1,
R_g2, Delta; web those of the belt and R_w, L_w, EA, v_ref. The gains Kp, Ki (web: also Kp_T,
Ki_T) may also be drawn (listed under [parameters] instead of [loop]). A parameter of another
model is refused. Every bound of a range must be >= 0 and low <= high; J_m, J_L, k, K_b, the
radii, L_w, EA and v_ref must stay > 0.

Defaults: the nominal drive, the gains and (shaft, belt) the reference's frequency are those of
the design answer for the model (`design_answer(model)`):
- shaft: `backlash_fmu.design("shaft", accuracy=0.02)`: its "plant" (J_m, b_m, b_L fixed; k and
  J_L the nominals of the tolerances), its "Kp" and "Ki" (best-damped rule), and its "poles"
  (the frequency is their mean natural frequency, `twin.reference_frequency`);
- belt: `backlash_fmu.design("belt", accuracy=2.2)`: likewise (K_b and J_L the nominals);
- web: `backlash_fmu.design("web", tension_accuracy=20, Kp_T=twin.KP_T, Ki_T=twin.KI_T)`: its
  plant (K_b, EA and L_w the nominals), its Kp, Ki, and the tension gains of the demo's web line
  (the answer's bound_T_sup is then that of the loop that runs); the reference is the demo's
  (twin.SPEED_AMPLITUDE, twin.SPEED_FREQUENCY, twin.T_REF).
The wear range of Delta, the tolerances, the shaft's and belt's reference amplitude and the run's
horizon, step and accuracies are the sweep's own (WEAR, TOLERANCES, AMPLITUDE, DEFAULT_RUN).

This module needs only the standard library until a config is built with its defaults: a
config is checked without them (`check`, what `--check` runs), and numpy is imported by `draw`.
"""

from __future__ import annotations

import functools
import math
import tomllib
from dataclasses import dataclass
from pathlib import Path
from typing import Any

MODELS = ("shaft", "belt", "web")
# The archive each model runs on (backlash_fmu.fmu_path's names).
ARCHIVES = {"shaft": "BacklashShaft", "belt": "BacklashBelt", "web": "BacklashWeb"}

# Order of the draws inside one sample, and of the table's columns: fixed, so a sample's values
# depend only on the seed and its index. The shaft's order is the sweep's original one (its
# tables stay byte for byte the same); the others put the drawn parameters first.
_BELT_DRIVE = ("J_L", "J_m", "b_m", "b_L", "R_1", "R_2", "R_g1", "R_g2")
PARAMETERS_OF = {
    "shaft": ("Delta", "k", "J_L", "J_m", "b_m", "b_L", "Kp", "Ki"),
    "belt": ("Delta", "K_b", *_BELT_DRIVE, "Kp", "Ki"),
    "web": ("Delta", "K_b", "EA", "L_w", *_BELT_DRIVE, "R_w", "v_ref", "Kp", "Ki", "Kp_T", "Ki_T"),
}
# The shaft's, under the sweep's original name.
PARAMETERS = PARAMETERS_OF["shaft"]
# Quantities that must be strictly positive for the FMU to accept them (docs/model.md §4, §8).
POSITIVE = {"J_m", "J_L", "k", "K_b", "R_1", "R_2", "R_g1", "R_g2", "R_w", "L_w", "EA", "v_ref"}

# The accuracies the defaults are designed for: the shaft's [m/s] is the demo's
# (backlash_fmu.demo); the belt's [rad/s] is a little above the load-speed bound of the belt
# drive at its FMU's Delta = 50 um (bound_sup 1.88 rad/s), so that its delta_max (58.6 um) lies
# inside the wear range below; the web's tension accuracy [N] is the demo's web line's
# (backlash_fmu.demo.web_design).
DESIGN_ACCURACY = 0.02
BELT_ACCURACY = 2.2
WEB_TENSION_ACCURACY = 20.0

# Delta is not the design's but a wear range. Shaft (0.775 mm designed): from a new gear pair
# (0.5 mm) to a worn one (3 mm, past the paper's largest measured gap read as 2 Delta). Belt and
# web (the same gear pair, R_g1 = 15 mm and R_g2 = 45 mm: module about 1 mm; Delta is the half gap
# on the pitch circle, 50 um in the FMU): from a new fine-pitch pair, 50 um of circumferential
# backlash (Delta = 25 um), to a worn one at four times that (Delta = 100 um); the designs'
# delta_max (58.6 um for the belt at 2.2 rad/s, 52.3 um for the web at 20 N) lie inside, so a
# sweep shows both sides of them.
WEAR = {"low": 0.5e-3, "high": 3e-3}
WEAR_OF = {"shaft": WEAR, "belt": {"low": 25e-6, "high": 100e-6}, "web": {"low": 25e-6, "high": 100e-6}}
# Manufacturing tolerances about the nominal values (relative half widths of uniform ranges):
# - k, J_L (shaft), J_L (belt): a machined shaft's stiffness and a load's inertia;
# - K_b (belt, web) +-15 %: a belt's stiffness follows its cords' modulus, its length and its
#   installed pretension, which spread more than a machined part's;
# - EA (web) +-10 %: the film's thickness (+-5 % on 50 um PET) times its modulus (+-5 %);
# - L_w (web) +-5 %: the free span between the rollers' tangent points moves with the rollers'
#   positions as assembled and with the web's wrap on them (a few cm on a metre).
TOLERANCES = {"k": 0.10, "J_L": 0.05}
TOLERANCES_OF = {
    "shaft": TOLERANCES,
    "belt": {"K_b": 0.15, "J_L": 0.05},
    "web": {"K_b": 0.15, "EA": 0.10, "L_w": 0.05},
}
# The demo's reversing reference on the shaft: its speed amplitude [m/s] (backlash_fmu.twin.SPEED),
# at the frequency of the design's poles. The belt's (30 rad/s on the motor, twin.SPEED_AMPLITUDE,
# the web line's) and the web's (twin.SPEED_AMPLITUDE at twin.SPEED_FREQUENCY, tension set point
# twin.T_REF) are read from backlash_fmu.twin when the defaults are built.
AMPLITUDE = 0.05
# The run of each model. Shaft: the demo's short horizon and step. Belt and web: the web demo's
# step, 0.1 ms (h times the drive's contact natural frequency, about 1170 rad/s, is 0.12:
# docs/model.md §3, "When the loop is closed at the communication step"); the belt's horizon
# holds twelve periods of its 121 Hz reference (the largest deviation comes in the second), the
# web's is the web demo's short one (the slow tension loop, poles -4.3 +- 4.0j, has its largest
# deviation after about 0.15 s). The web's speed accuracy is optional (absent: no speed criterion).
DEFAULT_RUN = {"horizon": 1.5, "h": 1e-3, "accuracy": DESIGN_ACCURACY}
DEFAULT_RUN_OF = {
    "shaft": DEFAULT_RUN,
    "belt": {"horizon": 0.1, "h": 1e-4, "accuracy": BELT_ACCURACY},
    "web": {"horizon": 0.5, "h": 1e-4, "tension_accuracy": WEB_TENSION_ACCURACY},
}

# The entries of each section but [parameters] (PARAMETERS_OF), in the order the errors list them.
ENTRIES_OF = {
    "shaft": {"loop": ("Kp", "Ki"), "reference": ("amplitude", "frequency"), "run": ("horizon", "h", "accuracy")},
    "belt": {"loop": ("Kp", "Ki"), "reference": ("amplitude", "frequency"), "run": ("horizon", "h", "accuracy")},
    "web": {"loop": ("Kp", "Ki", "Kp_T", "Ki_T"), "reference": ("amplitude", "frequency", "T_ref"),
            "run": ("horizon", "h", "accuracy", "tension_accuracy")},
}
ENTRIES = ENTRIES_OF["shaft"]
SECTIONS = {"parameters", *ENTRIES}
# The top-level keys of a config file besides its sections.
TOP_LEVEL = ("model",)

# The columns of a model's table after its parameters: the speed figures (`meets` only with a
# speed accuracy), then the web line's tension figures.
SPEED_COLUMNS = ("max_dev", "bound_sup", "ratio", "meets")
TENSION_COLUMNS = ("max_dev_T", "bound_T_sup", "ratio_T", "meets_T")


class ConfigError(ValueError):
    """A config the sweep refuses before any work starts; the message is one line."""


def _known_model(model: object, where: str) -> str:
    if not isinstance(model, str) or model not in MODELS:
        raise ConfigError(f"{where} = {model!r}: choose one of {', '.join(MODELS)}")
    return model


@functools.cache
def design_answer(model: str = "shaft") -> dict[str, Any]:
    """The design answer the defaults of `model` come from, computed once per process:
    `backlash_fmu.design("shaft", accuracy=DESIGN_ACCURACY)`, `design("belt",
    accuracy=BELT_ACCURACY)` or `design("web", tension_accuracy=WEB_TENSION_ACCURACY,
    Kp_T=twin.KP_T, Ki_T=twin.KI_T)` (the web with the tension gains its sweep runs, so that the
    answer's bound_T_sup is that of the loop that runs)."""
    from .. import design

    _known_model(model, "model")
    if model == "shaft":
        return design("shaft", accuracy=DESIGN_ACCURACY)
    if model == "belt":
        return design("belt", accuracy=BELT_ACCURACY)
    from ..twin import KI_T, KP_T

    return design("web", tension_accuracy=WEB_TENSION_ACCURACY, Kp_T=KP_T, Ki_T=KI_T)


def model_of_answer(answer: dict[str, Any]) -> str:
    """The model a design answer is for: its plant's form ("shaft", "belt" or "web")."""
    return _known_model(answer["plant"]["form"], "the design answer's plant form")


def defaults(answer: dict[str, Any]) -> dict[str, dict[str, Any]]:
    """The default of every section's entries, from a design answer (`design_answer(model)`; the
    model is its plant's form): its plant, its gains and (shaft, belt) the frequency of its
    poles, with the sweep's own wear range, tolerances, amplitude and run."""
    from ..twin import SPEED_AMPLITUDE, SPEED_FREQUENCY, T_REF, reference_frequency

    model = model_of_answer(answer)
    plant = answer["plant"]
    tolerances = TOLERANCES_OF[model]
    parameters: dict[str, Any] = {"Delta": dict(WEAR_OF[model])}
    for name in PARAMETERS_OF[model]:
        if name in tolerances:
            parameters[name] = {"nominal": plant[name], "tol": tolerances[name]}
        elif name in plant and name != "Delta":
            parameters[name] = plant[name]
    loop = {name: answer[name] for name in ENTRIES_OF[model]["loop"]}
    if model == "shaft":
        reference = {"amplitude": AMPLITUDE, "frequency": reference_frequency(answer["poles"])}
    elif model == "belt":
        reference = {"amplitude": SPEED_AMPLITUDE, "frequency": reference_frequency(answer["poles"])}
    else:
        reference = {"amplitude": SPEED_AMPLITUDE, "frequency": SPEED_FREQUENCY, "T_ref": T_REF}
    return {"parameters": parameters, "loop": loop, "reference": reference, "run": dict(DEFAULT_RUN_OF[model])}


@dataclass(frozen=True)
class Uniform:
    low: float
    high: float

    def describe(self) -> str:
        return f"uniform [{self.low!r}, {self.high!r}]"


@dataclass(frozen=True)
class Fixed:
    value: float

    def describe(self) -> str:
        return f"fixed {self.value!r}"


@dataclass
class Config:
    distributions: dict[str, Uniform | Fixed]
    amplitude: float
    frequency: float
    horizon: float
    h: float
    # The required load-speed accuracy epsilon (m/s on the shaft, rad/s on the belt and the web);
    # None on a web line swept without a speed criterion.
    accuracy: float | None
    source: str = "defaults"
    model: str = "shaft"
    # The web line's: the required tension accuracy eps_T [N] and the tension set point T_ref [N].
    tension_accuracy: float | None = None
    T_ref: float | None = None

    @property
    def archive(self) -> str:
        """The archive the model runs on ("BacklashShaft", "BacklashBelt" or "BacklashWeb")."""
        return ARCHIVES[self.model]

    @property
    def parameters(self) -> tuple[str, ...]:
        """The model's parameters, in the order of the draws and of the table's columns."""
        return PARAMETERS_OF[self.model]

    def settings(self) -> dict[str, Any]:
        """What every sample's run shares, as plain values (sent with each task;
        `twin.sample_row` reads them): "model", the reference, the run and the accuracies (web:
        also "T_ref" and "tension_accuracy"; "accuracy" None without a speed criterion)."""
        out: dict[str, Any] = {"amplitude": self.amplitude, "frequency": self.frequency, "horizon": self.horizon,
                               "h": self.h, "accuracy": self.accuracy}
        if self.model == "web":
            out.update(T_ref=self.T_ref, tension_accuracy=self.tension_accuracy)
        out["model"] = self.model
        return out

    def columns(self) -> tuple[str, ...]:
        """The table's columns: "sample", the parameters, the speed figures (max_dev, bound_sup,
        ratio, and meets when a speed accuracy is set) and, on the web line, the tension figures
        (max_dev_T, bound_T_sup, ratio_T, meets_T). The shaft's are the sweep's original ones."""
        return columns(self.model, speed_accuracy=self.accuracy is not None)

    def draw(self, samples: int, seed: int) -> list[dict[str, float]]:
        """Every sample's parameters, drawn here once: sample i's values depend only on the seed
        and i (draws in the model's PARAMETERS_OF order, sample after sample), never on who runs
        it."""
        import numpy as np  # here, so that a config can be checked without the venv (--check)

        rng = np.random.default_rng(seed)
        out = []
        for _ in range(samples):
            values = {}
            for name in PARAMETERS_OF[self.model]:
                d = self.distributions[name]
                values[name] = float(rng.uniform(d.low, d.high)) if isinstance(d, Uniform) else float(d.value)
            out.append(values)
        return out


def columns(model: str = "shaft", speed_accuracy: bool = True) -> tuple[str, ...]:
    """The columns of `model`'s table (Config.columns); `speed_accuracy`: whether a speed
    accuracy is set (else no `meets` column)."""
    speed = SPEED_COLUMNS if speed_accuracy else SPEED_COLUMNS[:-1]
    return ("sample", *PARAMETERS_OF[model], *speed, *(TENSION_COLUMNS if model == "web" else ()))


def _number(where: str, value: object) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise ConfigError(f"{where}: expected a number, got {value!r}")
    value = float(value)
    if not math.isfinite(value):
        raise ConfigError(f"{where}: must be finite, got {value!r}")
    return value


def _distribution(name: str, spec: object) -> Uniform | Fixed:
    where = f"parameters.{name}"
    if not isinstance(spec, dict):
        value = _number(where, spec)
        if value < 0 or (name in POSITIVE and value == 0):
            raise ConfigError(f"{where}: must be {'> 0' if name in POSITIVE else '>= 0'}, got {value!r}")
        return Fixed(value)
    keys = set(spec)
    if keys == {"low", "high"}:
        low, high = _number(f"{where}.low", spec["low"]), _number(f"{where}.high", spec["high"])
    elif keys == {"nominal", "tol"}:
        nominal, tol = _number(f"{where}.nominal", spec["nominal"]), _number(f"{where}.tol", spec["tol"])
        if tol < 0:
            raise ConfigError(f"{where}: negative tolerance tol = {tol!r}")
        low, high = nominal * (1 - tol), nominal * (1 + tol)
    else:
        raise ConfigError(f"{where}: expected {{ low, high }} or {{ nominal, tol }}, got keys {sorted(keys)}")
    if low < 0 or high < 0:
        raise ConfigError(f"{where}: negative range [{low!r}, {high!r}]")
    if low > high:
        raise ConfigError(f"{where}: inverted range, low = {low!r} > high = {high!r}")
    if name in POSITIVE and low == 0:
        raise ConfigError(f"{where}: range must stay > 0, got low = 0")
    return Uniform(low, high)


def _section(doc: dict, name: str, model: str) -> dict:
    """The entries given in section [name], each a known one for `model`."""
    given = doc.get(name, {})
    if not isinstance(given, dict):
        raise ConfigError(f"[{name}] must be a table")
    known = ENTRIES_OF[model][name]
    unknown = sorted(set(given) - set(known))
    if unknown:
        where = "" if model == "shaft" else f" for the {model}"
        raise ConfigError(f"[{name}]: unknown entry {unknown[0]!r}{where} (known: {', '.join(known)})")
    return given


def model_of(doc: dict, model: str | None = None) -> str:
    """The model a config is for: the one the document names (`model = "..."` at its top), the
    one given (`model`, from --model), or "shaft" when neither is. Raises ConfigError when both
    are given and differ, or for an unknown model."""
    named = doc.get("model")
    if named is not None:
        named = _known_model(named, "model")
    if model is not None:
        model = _known_model(model, "--model")
        if named is not None and named != model:
            raise ConfigError(f"the config is for model = {named!r} but --model {model} was given")
        return model
    return "shaft" if named is None else named


def build(doc: dict, source: str = "defaults", answer: dict[str, Any] | None = None,
          model: str | None = None) -> Config:
    """The config from a parsed TOML document (empty: all defaults), validated, for the model
    `model_of(doc, model)`; the defaults from the design answer `answer` (default:
    `design_answer(model)`; it must be for the same model)."""
    model = model_of(doc, model)
    if answer is None:
        answer = design_answer(model)
    elif model_of_answer(answer) != model:
        raise ConfigError(f"the design answer is for model = {model_of_answer(answer)!r}, the config for {model!r}")
    return _validated(doc, source, defaults(answer), model)


def check(doc: dict, source: str = "defaults", model: str | None = None) -> None:
    """Validates a parsed TOML document as `build` does, with the standard library only: every
    entry given is checked, and the defaults (valid by construction) are not computed. Raises
    ConfigError on the error `build` would report."""
    _validated(doc, source, None, model_of(doc, model))


def _validated(doc: dict, source: str, default: dict[str, dict[str, Any]] | None, model: str) -> Config | None:
    """The config of `doc` over the defaults `default` for `model`; with None, only the entries
    of `doc` and the defaults that are the sweep's own are checked, and nothing is returned."""
    sections = set(ENTRIES_OF[model]) | {"parameters"}
    unknown = sorted(set(doc) - sections - set(TOP_LEVEL))
    if unknown:
        raise ConfigError(f"unknown section [{unknown[0]}] (known: {', '.join(sorted(sections))})")
    params = doc.get("parameters", {})
    if not isinstance(params, dict):
        raise ConfigError("[parameters] must be a table")
    known = PARAMETERS_OF[model]
    for name in params:
        if name not in known:
            other = [m for m in MODELS if m != model and name in PARAMETERS_OF[m]]
            hint = f"; a parameter of the {' and the '.join(other)}" if other else ""
            where = "" if model == "shaft" and not other else f" for the {model}"
            raise ConfigError(f"unknown parameter {name!r}{where} (known: {', '.join(known)}){hint}")
    loop = _section(doc, "loop", model)
    both = sorted(set(params) & set(loop))
    if both:
        raise ConfigError(f"{both[0]} given both in [parameters] and [loop]")
    own = {"parameters": {"Delta": WEAR_OF[model]}, "loop": {},
           "reference": {"amplitude": AMPLITUDE} if model == "shaft" else {}, "run": DEFAULT_RUN_OF[model]}
    base = own if default is None else default
    specs = {**base["parameters"], **base["loop"], **loop, **params}
    distributions = {name: _distribution(name, specs[name]) for name in known if name in specs}
    reference = {k: _number(f"reference.{k}", v)
                 for k, v in {**base["reference"], **_section(doc, "reference", model)}.items()}
    run = {k: _number(f"run.{k}", v) for k, v in {**base["run"], **_section(doc, "run", model)}.items()}
    for key in ENTRIES_OF[model]["run"]:
        if key in run and run[key] <= 0:
            raise ConfigError(f"run.{key}: must be > 0, got {run[key]!r}")
    if run["h"] > run["horizon"]:
        raise ConfigError(f"run.h = {run['h']!r} is longer than run.horizon = {run['horizon']!r}")
    for key in ("frequency", "T_ref"):
        if reference.get(key, 0.0) < 0:
            raise ConfigError(f"reference.{key}: must be >= 0, got {reference[key]!r}")
    if default is None:
        return None
    web = model == "web"
    return Config(distributions, reference["amplitude"], reference["frequency"], run["horizon"], run["h"],
                  run.get("accuracy"), source, model, run["tension_accuracy"] if web else None,
                  reference["T_ref"] if web else None)


def read(path: Path | None) -> tuple[dict, str]:
    """The parsed TOML document of the config file at `path` and the source to report ({} and
    "defaults" without a file)."""
    if path is None:
        return {}, "defaults"
    try:
        with open(path, "rb") as f:
            return tomllib.load(f), str(path)
    except OSError as e:
        raise ConfigError(f"cannot read config {path}: {e.strerror}") from None
    except tomllib.TOMLDecodeError as e:
        raise ConfigError(f"config {path} is not valid TOML: {e}") from None


def load(path: Path | None, answer: dict[str, Any] | None = None, model: str | None = None) -> Config:
    """The config of the file at `path` (None: all defaults), validated, for the model it names
    or `model` (--model; None: not given; both given and different: refused; neither: "shaft");
    the defaults from the design answer `answer` (default: `design_answer(model)`)."""
    doc, source = read(path)
    try:
        return build(doc, source, answer, model)
    except ConfigError as e:
        raise ConfigError(f"config {path}: {e}") from None


def load_checked(path: Path | None, model: str | None = None) -> None:
    """Checks the config file at `path` for `model` as `load` would, with the standard library
    only."""
    doc, source = read(path)
    try:
        check(doc, source, model)
    except ConfigError as e:
        raise ConfigError(f"config {path}: {e}") from None

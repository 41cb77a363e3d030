"""What a sweep draws and how each sample runs: defaults, the TOML config file, validation, and
the draws of every sample.

Config file (TOML, every entry optional; an entry replaces the default of the same name):

    [parameters]                  # BacklashShaft parameters (docs/model.md §4), SI units
    Delta = { low = 0.5e-3, high = 3e-3 }   # uniform on [low, high]
    k     = { nominal = 200.0, tol = 0.10 } # uniform on nominal * [1 - tol, 1 + tol]
    J_L   = { nominal = 2.55, tol = 0.05 }
    J_m   = 2.28                            # a plain number: fixed in every sample

    [loop]                        # the PI on the motor speed, closed outside the FMU
    Kp = 42.70304505387717
    Ki = 179.2424837177854

    [reference]                   # w_ref(t) = amplitude * sin(2 pi frequency t)
    amplitude = 0.05
    frequency = 1.41

    [run]
    horizon = 1.5                 # simulated seconds per run
    h = 1e-3                      # communication step [s]
    accuracy = 0.02               # required load-speed accuracy epsilon [m/s]

Parameters: J_m, J_L, b_m, b_L, k, Delta, and the gains Kp, Ki may also be drawn (listed under
[parameters] instead of [loop]). Every bound of a range must be >= 0 and low <= high.
"""

from __future__ import annotations

import math
import tomllib
from dataclasses import dataclass
from pathlib import Path

# Order of the draws inside one sample, and of the table's columns: fixed, so a sample's values
# depend only on the seed and its index.
PARAMETERS = ("Delta", "k", "J_L", "J_m", "b_m", "b_L", "Kp", "Ki")
# Quantities that must be strictly positive for the FMU to accept them (docs/model.md §4).
POSITIVE = {"J_m", "J_L", "k"}

# The test rigs, kept in tests/fixtures/rigs.toml. Read here, when the command line builds its
# config (the path is this package's, in the repository); the workers get the drawn values,
# never this module.
RIGS_FIXTURE = Path(__file__).resolve().parents[1] / "tests" / "fixtures" / "rigs.toml"


def _rig(model: str) -> dict[str, float]:
    """A model's rig of the fixture: its parameter sets applied in order (tests/python/rigs.py)."""
    with open(RIGS_FIXTURE, "rb") as f:
        fixture = tomllib.load(f)
    values: dict[str, float] = {}
    for name in fixture["rigs"][model]["parameters"]:
        values.update(fixture["sets"][name])
    return values


# The nominal drive: the fixture's BacklashShaft rig, the paper's experiment in shaft form
# (PlantParams::paper_rig, the rectilinear ECP system). Delta is not the rig's (2.69 mm) but a
# wear range, from a new gear pair (0.5 mm) to a worn one (3 mm, past the paper's largest
# measured gap read as 2 Delta); k and J_L: manufacturing tolerances about the rig's values.
_SHAFT = _rig("BacklashShaft")
DEFAULT_PARAMETERS: dict[str, object] = {
    "Delta": {"low": 0.5e-3, "high": 3e-3},
    "k": {"nominal": _SHAFT["k"], "tol": 0.10},
    "J_L": {"nominal": _SHAFT["J_L"], "tol": 0.05},
    "J_m": _SHAFT["J_m"],
    "b_m": _SHAFT["b_m"],
    "b_L": _SHAFT["b_L"],
}
# The demo's PI gains: Kp, Ki of `cargo xtask design --accuracy 0.02 --json` (best-damped rule
# on the nominal rig); one controller for every drive of the line. Not the fixture's
# shaft_gains (Kp = 42, Ki = 180, the tests' grid-search round values): the demo's own.
DEFAULT_LOOP = {"Kp": 42.70304505387717, "Ki": 179.2424837177854}
# The demo's reversing reference: its SPEED sine at the closed-loop poles' natural frequency,
# mean |pole| / 2 pi of the "poles" of the same command's output.
DEFAULT_REFERENCE = {"amplitude": 0.05, "frequency": 1.4103246998179486}
# The demo's short horizon and step, and its accuracy epsilon [m/s].
DEFAULT_RUN = {"horizon": 1.5, "h": 1e-3, "accuracy": 0.02}

SECTIONS = {"parameters", "loop", "reference", "run"}


class ConfigError(ValueError):
    """A config the sweep refuses before any work starts; the message is one line."""


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
    accuracy: float
    source: str = "defaults"

    def settings(self) -> dict[str, float]:
        """What every sample's run shares, as plain numbers (sent with each task)."""
        return {"amplitude": self.amplitude, "frequency": self.frequency, "horizon": self.horizon, "h": self.h,
                "accuracy": self.accuracy}

    def draw(self, samples: int, seed: int) -> list[dict[str, float]]:
        """Every sample's parameters, drawn here once: sample i's values depend only on the seed
        and i (draws in PARAMETERS order, sample after sample), never on who runs it."""
        import numpy as np  # here, so that a config can be checked without the venv (--check)

        rng = np.random.default_rng(seed)
        out = []
        for _ in range(samples):
            values = {}
            for name in PARAMETERS:
                d = self.distributions[name]
                values[name] = float(rng.uniform(d.low, d.high)) if isinstance(d, Uniform) else float(d.value)
            out.append(values)
        return out


def _number(where: str, value) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise ConfigError(f"{where}: expected a number, got {value!r}")
    value = float(value)
    if not math.isfinite(value):
        raise ConfigError(f"{where}: must be finite, got {value!r}")
    return value


def _distribution(name: str, spec) -> Uniform | Fixed:
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


def _section(doc: dict, name: str, defaults: dict) -> dict:
    given = doc.get(name, {})
    if not isinstance(given, dict):
        raise ConfigError(f"[{name}] must be a table")
    unknown = sorted(set(given) - set(defaults))
    if unknown:
        raise ConfigError(f"[{name}]: unknown entry {unknown[0]!r} (known: {', '.join(defaults)})")
    return {**defaults, **given}


def build(doc: dict, source: str = "defaults") -> Config:
    """The config from a parsed TOML document (empty: all defaults), validated."""
    unknown = sorted(set(doc) - SECTIONS)
    if unknown:
        raise ConfigError(f"unknown section [{unknown[0]}] (known: {', '.join(sorted(SECTIONS))})")
    params = doc.get("parameters", {})
    if not isinstance(params, dict):
        raise ConfigError("[parameters] must be a table")
    for name in params:
        if name not in PARAMETERS:
            raise ConfigError(f"unknown parameter {name!r} (known: {', '.join(PARAMETERS)})")
    loop = _section(doc, "loop", DEFAULT_LOOP)
    both = sorted(set(params) & set(doc.get("loop", {})))
    if both:
        raise ConfigError(f"{both[0]} given both in [parameters] and [loop]")
    specs = {**DEFAULT_PARAMETERS, **loop, **params}
    distributions = {name: _distribution(name, specs[name]) for name in PARAMETERS}
    reference = {k: _number(f"reference.{k}", v) for k, v in _section(doc, "reference", DEFAULT_REFERENCE).items()}
    run = {k: _number(f"run.{k}", v) for k, v in _section(doc, "run", DEFAULT_RUN).items()}
    for key in ("horizon", "h", "accuracy"):
        if run[key] <= 0:
            raise ConfigError(f"run.{key}: must be > 0, got {run[key]!r}")
    if run["h"] > run["horizon"]:
        raise ConfigError(f"run.h = {run['h']!r} is longer than run.horizon = {run['horizon']!r}")
    if reference["frequency"] < 0:
        raise ConfigError(f"reference.frequency: must be >= 0, got {reference['frequency']!r}")
    return Config(distributions, reference["amplitude"], reference["frequency"], run["horizon"], run["h"],
                  run["accuracy"], source)


def load(path: Path | None) -> Config:
    if path is None:
        return build({})
    try:
        with open(path, "rb") as f:
            doc = tomllib.load(f)
    except OSError as e:
        raise ConfigError(f"cannot read config {path}: {e.strerror}") from None
    except tomllib.TOMLDecodeError as e:
        raise ConfigError(f"config {path} is not valid TOML: {e}") from None
    try:
        return build(doc, str(path))
    except ConfigError as e:
        raise ConfigError(f"config {path}: {e}") from None

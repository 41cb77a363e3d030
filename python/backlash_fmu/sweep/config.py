"""What a sweep draws and how each sample runs: defaults, the TOML config file, validation, and
the draws of every sample.

Config file (TOML, every entry optional; an entry replaces the default of the same name):

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

Parameters: J_m, J_L, b_m, b_L, k, Delta, and the gains Kp, Ki may also be drawn (listed under
[parameters] instead of [loop]). Every bound of a range must be >= 0 and low <= high.

Defaults: the nominal drive, the gains and the reference's frequency are those of the design
answer for the shaft at the default accuracy, `backlash_fmu.design("shaft", accuracy=0.02)`
(DESIGN_ACCURACY): its "plant" (J_m, b_m, b_L fixed; k and J_L the nominals of the tolerances),
its "Kp" and "Ki" (best-damped rule), and its "poles" (the frequency is their mean natural
frequency, `twin.reference_frequency`). The wear range of Delta, the tolerances of k and J_L,
the reference's amplitude and the run's horizon, step and accuracy are the sweep's own (WEAR,
TOLERANCES, AMPLITUDE, DEFAULT_RUN).

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

# Order of the draws inside one sample, and of the table's columns: fixed, so a sample's values
# depend only on the seed and its index.
PARAMETERS = ("Delta", "k", "J_L", "J_m", "b_m", "b_L", "Kp", "Ki")
# Quantities that must be strictly positive for the FMU to accept them (docs/model.md §4).
POSITIVE = {"J_m", "J_L", "k"}

# The accuracy the default gains are designed for [m/s]: the demo's (backlash_fmu.demo).
DESIGN_ACCURACY = 0.02
# Delta is not the design's (0.775 mm) but a wear range, from a new gear pair (0.5 mm) to a worn
# one (3 mm, past the paper's largest measured gap read as 2 Delta); k and J_L: manufacturing
# tolerances about the nominal drive's values.
WEAR = {"low": 0.5e-3, "high": 3e-3}
TOLERANCES = {"k": 0.10, "J_L": 0.05}
# The demo's reversing reference: its speed amplitude [m/s] (backlash_fmu.twin.SPEED), at the
# frequency of the design's poles.
AMPLITUDE = 0.05
# The demo's short horizon and step, and its accuracy epsilon [m/s].
DEFAULT_RUN = {"horizon": 1.5, "h": 1e-3, "accuracy": DESIGN_ACCURACY}

# The entries of each section but [parameters] (PARAMETERS), in the order the errors list them.
ENTRIES = {
    "loop": ("Kp", "Ki"),
    "reference": ("amplitude", "frequency"),
    "run": tuple(DEFAULT_RUN),
}
SECTIONS = {"parameters", *ENTRIES}


class ConfigError(ValueError):
    """A config the sweep refuses before any work starts; the message is one line."""


@functools.cache
def design_answer() -> dict[str, Any]:
    """The design answer the defaults come from: `backlash_fmu.design("shaft",
    accuracy=DESIGN_ACCURACY)`, computed once per process."""
    from .. import design

    return design("shaft", accuracy=DESIGN_ACCURACY)


def defaults(answer: dict[str, Any]) -> dict[str, dict[str, Any]]:
    """The default of every section's entries, from a shaft design answer (`design_answer()`):
    its plant, its gains and the frequency of its poles, with the sweep's own wear range,
    tolerances, amplitude and run."""
    from ..twin import reference_frequency

    plant = answer["plant"]
    return {
        "parameters": {
            "Delta": dict(WEAR),
            "k": {"nominal": plant["k"], "tol": TOLERANCES["k"]},
            "J_L": {"nominal": plant["J_L"], "tol": TOLERANCES["J_L"]},
            "J_m": plant["J_m"],
            "b_m": plant["b_m"],
            "b_L": plant["b_L"],
        },
        "loop": {"Kp": answer["Kp"], "Ki": answer["Ki"]},
        "reference": {"amplitude": AMPLITUDE, "frequency": reference_frequency(answer["poles"])},
        "run": dict(DEFAULT_RUN),
    }


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


def _section(doc: dict, name: str) -> dict:
    """The entries given in section [name], each a known one."""
    given = doc.get(name, {})
    if not isinstance(given, dict):
        raise ConfigError(f"[{name}] must be a table")
    known = ENTRIES[name]
    unknown = sorted(set(given) - set(known))
    if unknown:
        raise ConfigError(f"[{name}]: unknown entry {unknown[0]!r} (known: {', '.join(known)})")
    return given


def build(doc: dict, source: str = "defaults", answer: dict[str, Any] | None = None) -> Config:
    """The config from a parsed TOML document (empty: all defaults), validated; the defaults
    from the design answer `answer` (default: `design_answer()`)."""
    return _validated(doc, source, defaults(design_answer() if answer is None else answer))


def check(doc: dict, source: str = "defaults") -> None:
    """Validates a parsed TOML document as `build` does, with the standard library only: every
    entry given is checked, and the defaults (valid by construction) are not computed. Raises
    ConfigError on the error `build` would report."""
    _validated(doc, source, None)


def _validated(doc: dict, source: str, default: dict[str, dict[str, Any]] | None) -> Config | None:
    """The config of `doc` over the defaults `default`; with None, only the entries of `doc` and
    the defaults that are the sweep's own are checked, and nothing is returned."""
    unknown = sorted(set(doc) - SECTIONS)
    if unknown:
        raise ConfigError(f"unknown section [{unknown[0]}] (known: {', '.join(sorted(SECTIONS))})")
    params = doc.get("parameters", {})
    if not isinstance(params, dict):
        raise ConfigError("[parameters] must be a table")
    for name in params:
        if name not in PARAMETERS:
            raise ConfigError(f"unknown parameter {name!r} (known: {', '.join(PARAMETERS)})")
    loop = _section(doc, "loop")
    both = sorted(set(params) & set(loop))
    if both:
        raise ConfigError(f"{both[0]} given both in [parameters] and [loop]")
    own = {"parameters": {"Delta": WEAR}, "loop": {}, "reference": {"amplitude": AMPLITUDE}, "run": DEFAULT_RUN}
    base = own if default is None else default
    specs = {**base["parameters"], **base["loop"], **loop, **params}
    distributions = {name: _distribution(name, specs[name]) for name in PARAMETERS if name in specs}
    reference = {k: _number(f"reference.{k}", v)
                 for k, v in {**base["reference"], **_section(doc, "reference")}.items()}
    run = {k: _number(f"run.{k}", v) for k, v in {**base["run"], **_section(doc, "run")}.items()}
    for key in ("horizon", "h", "accuracy"):
        if run[key] <= 0:
            raise ConfigError(f"run.{key}: must be > 0, got {run[key]!r}")
    if run["h"] > run["horizon"]:
        raise ConfigError(f"run.h = {run['h']!r} is longer than run.horizon = {run['horizon']!r}")
    if reference.get("frequency", 0.0) < 0:
        raise ConfigError(f"reference.frequency: must be >= 0, got {reference['frequency']!r}")
    if default is None:
        return None
    return Config(distributions, reference["amplitude"], reference["frequency"], run["horizon"], run["h"],
                  run["accuracy"], source)


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


def load(path: Path | None, answer: dict[str, Any] | None = None) -> Config:
    """The config of the file at `path` (None: all defaults), validated; the defaults from the
    design answer `answer` (default: `design_answer()`)."""
    doc, source = read(path)
    try:
        return build(doc, source, answer)
    except ConfigError as e:
        raise ConfigError(f"config {path}: {e}") from None


def load_checked(path: Path | None) -> None:
    """Checks the config file at `path` as `load` would, with the standard library only."""
    doc, source = read(path)
    try:
        check(doc, source)
    except ConfigError as e:
        raise ConfigError(f"config {path}: {e}") from None

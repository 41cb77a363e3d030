"""Exact compliance + backlash drive-train FMUs, and the design study that sizes them.

    import backlash_fmu
    answer = backlash_fmu.design("shaft", accuracy=0.02)        # the design study (docs/model.md §3)
    path = backlash_fmu.fmu_path("BacklashShaft", fmi=3)       # the FMI 3.0 archive, shipped here

- `design(model, accuracy=None, tension_accuracy=None, **parameters)`: the design answer, the
  same keys and numbers as `backlash design ... --json`;
- `identify(model, data, fit=None, **known)`: a drive's half gap, stiffness and load from one
  measured run (a CSV path or a table), with 95 % intervals: the same keys and numbers as
  `backlash identify ... --json` (docs/model.md §11);
- `fmu_path(model, fmi=2)`: the FMI 2.0 or FMI 3.0 archive of a plant (`MODELS`: BacklashShaft,
  BacklashBelt, BacklashWeb, BacklashTwoStage) or of BacklashController, built from the same
  sources as this package;
- `backlash_fmu.fmu`: the driver of the archives (FMI 2.0 and 3.0, Co-Simulation and Model
  Exchange); `backlash_fmu.twin`: the twin closed-loop runs; `backlash_fmu.sweep`: tolerance
  sweeps; `backlash_fmu.demo`: the paper's experiments.
"""

from __future__ import annotations

import json
import os
from collections.abc import Mapping
from pathlib import Path

from . import fmu

__all__ = ["design", "design_json", "identify", "identify_json", "fmu_path", "MODELS", "CONTROLLERS"]

# The plants whose archives ship with the package, as their manifest lists them, and the
# controllers (BacklashController, docs/model.md §9).
MODELS: tuple[str, ...] = fmu.models(fmu.PACKAGED)
CONTROLLERS: tuple[str, ...] = fmu.models(fmu.PACKAGED, fmu.CONTROLLER_MANIFEST)


def design(model: str, accuracy: float | None = None, tension_accuracy: float | None = None,
           **parameters: float) -> dict:
    """The design answer for `model` ("shaft", "belt", "web" or "two-stage"): `accuracy` is the
    load-speed accuracy ε [rad/s] (required for shaft, belt and two-stage), `tension_accuracy`
    the web line's ε_T [N] (required for web); `parameters` by the FMUs' variable names (J_m,
    J_L, b_m, b_L, k or K_b, Delta, R_1, R_2, R_g1, R_g2, R_w, L_w, EA, v_ref, Kp, Ki, Kp_T, Ki_T;
    shaft and belt: the bearing friction tau_c_m, tau_c_L, peak_m, peak_L; two-stage: J_i, b_i,
    n_1, n_2, k_1, k_2, Delta_1, Delta_2) replace the defaults.
    Returns the answer as `backlash design ... --json` prints it. Raises ValueError with the
    reason on bad input (an unknown model or parameter, a non-finite or out-of-range value)."""
    return json.loads(design_json(model, accuracy, tension_accuracy, **parameters))


def design_json(model: str, accuracy: float | None = None, tension_accuracy: float | None = None,
                **parameters: float) -> str:
    """`design`'s answer as the JSON text `backlash design ... --json` prints (one key a line,
    no final newline)."""
    from . import _native  # the design library, compiled

    if not isinstance(model, str):
        raise ValueError(f"model = {model!r}: choose 'shaft', 'belt', 'web' or 'two-stage'")
    values = {name: _number(name, value) for name, value in parameters.items()}
    return _native.design_json(
        model,
        None if accuracy is None else _number("accuracy", accuracy),
        None if tension_accuracy is None else _number("tension_accuracy", tension_accuracy),
        list(values.items()),
    )


def identify(model: str, data, fit=None, **known: float) -> dict:
    """Identifies the drive `model` ("shaft", "belt" or "web") from one measured run: `data` is
    the path of a CSV file or a table (a dict of column name -> sequence, a pandas DataFrame or
    anything with `.columns`, a numpy structured array) with `time`, `tau_m` and measured
    outputs (docs/model.md §11); `fit` the names to estimate (a list, or one comma-separated
    string; default: Delta, the stiffness, J_L, b_L, u0); `known` the other parameters by their
    FMU names, and `accuracy` / `tension_accuracy` to check the drive against a design accuracy.
    Returns the answer as `backlash identify ... --json` prints it. Raises ValueError with the
    one-line reason on bad data (a missing or unknown column, a non-uniform or decreasing time,
    NaN, too few samples) or input."""
    return json.loads(identify_json(model, data, fit, **known))


def identify_json(model: str, data, fit=None, **known: float) -> str:
    """`identify`'s answer as the JSON text `backlash identify ... --json` prints."""
    from . import _native  # the identification library, compiled

    if not isinstance(model, str):
        raise ValueError(f"model = {model!r}: choose 'shaft', 'belt' or 'web'")
    if isinstance(fit, str):
        fit = fit.split(",")
    elif fit is not None:
        fit = [str(name) for name in fit]
    values = [(name, _number(name, value)) for name, value in known.items()]
    if isinstance(data, (str, os.PathLike)):
        return _native.identify_json(model, os.fspath(data), None, fit, values)
    return _native.identify_json(model, None, _columns(data), fit, values)


def _columns(data) -> list[tuple[str, list[float]]]:
    """A table as (column name, values): a numpy structured array, anything with `.columns`
    (a pandas DataFrame), or a mapping of name -> sequence."""
    names = getattr(getattr(data, "dtype", None), "names", None)
    if names:
        pass
    elif hasattr(data, "columns"):
        names = list(data.columns)
    elif isinstance(data, Mapping):
        names = list(data.keys())
    else:
        raise ValueError("data: give the path of a CSV file or a table (a dict of columns, a pandas "
                         "DataFrame, a numpy structured array)")
    columns = []
    for name in names:
        values = data[name]
        values = values.tolist() if hasattr(values, "tolist") else values
        try:
            columns.append((str(name), [float(v) for v in values]))
        except (TypeError, ValueError):
            raise ValueError(f"column {name}: the values are not all numbers") from None
    return columns


def _number(name: str, value: object) -> float:
    """`value` as a float; a bool or a non-number is refused (NaN and ±inf are refused by the
    study with its reason)."""
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise ValueError(f"{name} = {value!r} is not a number")
    return float(value)


def fmu_path(model: str, fmi: int = 2) -> Path:
    """The FMI 2.0 (`fmi=2`) or FMI 3.0 (`fmi=3`) archive of `model` ("BacklashShaft",
    "BacklashBelt", "BacklashWeb", "BacklashTwoStage" or "BacklashController") shipped in this
    package. Raises ValueError for another model or standard, FileNotFoundError if the archive is
    missing from the installation."""
    if model not in MODELS + CONTROLLERS:
        raise ValueError(f"model = {model!r}: choose one of {', '.join(MODELS + CONTROLLERS)}")
    if fmi not in (2, 3):
        raise ValueError(f"fmi = {fmi!r}: choose 2 or 3")
    path = fmu.packaged_path(model, fmi)
    if not path.is_file():
        raise FileNotFoundError(f"{path}: this installation of backlash_fmu lacks its archive")
    return path


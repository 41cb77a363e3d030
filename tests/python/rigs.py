"""Parameter sets shared by the tests, named as the FMU parameters of docs/model.md §4."""

from __future__ import annotations

import tomllib
from pathlib import Path

from reference import Plant

# The rigs, kept in tests/fixtures/rigs.toml (read by the cross-platform test too).
_FIXTURE = tomllib.loads((Path(__file__).resolve().parents[1] / "fixtures" / "rigs.toml").read_text())
_SETS: dict[str, dict[str, float]] = _FIXTURE["sets"]


def _merged(*names: str) -> dict[str, float]:
    """The parameter sets `names` applied in order."""
    out: dict[str, float] = {}
    for name in names:
        out.update(_SETS[name])
    return out


# The paper's experiment in shaft form (docs/model.md §4): J_m, J_L, k, b; its largest gap read
# as the total free play 2 Delta.
PAPER = _merged("paper")
SHAFT = _merged("paper", "shaft")
# A belt drive of the same inertias (the fixture says why these values).
BELT = _merged("paper", "belt")
SHAFT_GAINS = _merged("shaft_gains")
BELT_GAINS = _merged("belt_gains")
# BacklashWeb with its web decoupled: its drive train is BELT, which the drive-train tests check
# it against; the web itself is checked in test_web.py.
WEB_DECOUPLED = _merged("paper", "belt", "web_decoupled")

RIGS = {model: (_merged(*rig["parameters"]), _merged(rig["gains"])) for model, rig in _FIXTURE["rigs"].items()}

# The web span's parameters and the tension loop's gains: not part of the drive train.
WEB_ONLY = ("R_w", "L_w", "EA", "v_ref", "Kp_T", "Ki_T")
# Bearing friction (docs/model.md §12), which the plant of §1 does not have.
FRICTION = ("tau_c_m", "tau_c_L", "peak_m", "peak_L")


def plant_of(model: str, params: dict) -> Plant:
    """The generic plant (docs/model.md §1 table) for an FMU's parameter values, in the form its
    parameters name (docs/model.md §4): a shaft's stiffness k or a belt's K_b; a web line's drive
    train alone (its web decoupled, WEB_DECOUPLED). Without bearing friction: a tau_c above 0
    is refused (reference_friction.py solves that plant)."""
    if any(params.get(name, 0.0) != 0.0 for name in ("tau_c_m", "tau_c_L")):
        raise ValueError(f"{model}: bearing friction (tau_c > 0) is not the plant of docs/model.md §1")
    p = {k: v for k, v in params.items() if k not in ("Kp", "Ki", *WEB_ONLY, *FRICTION)}
    if "k" in p:
        return Plant.shaft(**p)
    if "K_b" in p:
        return Plant.belt(**p)
    raise ValueError(f"{model}: its parameters {sorted(p)} name no drive train of docs/model.md §1")


def with_delta(params: dict, delta: float) -> dict:
    """`params` with every half gap at `delta`: the single gap's Delta, or each mesh's Delta_j of
    a gearbox (docs/model.md §10)."""
    meshes = [name for name in params if name.startswith("Delta_")]
    return {**params, **{name: delta for name in meshes or ["Delta"]}}


# The two-stage rig geared: ratios other than 1 and unequal gaps, so that a ratio on the wrong
# side of a mesh, or one mesh's gap taken for the other's, changes what the tests compare.
TWO_STAGE_GEARED = {**RIGS["BacklashTwoStage"][0], "n_1": 2.5, "n_2": 1.6, "Delta_2": 2.2e-3}

"""Parameter sets shared by the tests, named as the FMU parameters of docs/model.md §4."""

from __future__ import annotations

from reference import Plant

# The paper's experiment in shaft form (docs/model.md §4): J_m, J_L, k, b. Its largest gap,
# 5.38 mm, read as the total free play 2 Delta (the paper's nomenclature, docs/model.md §5).
PAPER = {"J_m": 2.28, "J_L": 2.55, "b_m": 0.05, "b_L": 0.05}
SHAFT = {**PAPER, "k": 200.0, "Delta": 5.38e-3 / 2}

# A belt drive of the same inertias: r_m = 0.1 m, r_L = 0.08 * 0.075 / 0.05 = 0.12 m,
# g = (0.08 / 0.05) Delta = 3.2 mm; K_b puts its resonance (14 rad/s) near the shaft's (13 rad/s)
# and the reflected load inertia near the motor's, so that a motor-speed PI can damp it.
BELT = {**PAPER, "K_b": 2.0e4, "R_1": 0.1, "R_2": 0.08, "R_g1": 0.05, "R_g2": 0.075, "Delta": 2.0e-3}

# PI gains (Kp in N.m.s/rad, Ki in N.m/rad) chosen by a grid search that maximises the smallest
# damping ratio among the eigenvalues of A_cl (docs/model.md §3); the tests re-check the damping.
# Shaft: min zeta = 0.51, slowest decay rate 4.0 /s.  Belt: min zeta = 0.31, slowest 3.9 /s.
SHAFT_GAINS = {"Kp": 42.0, "Ki": 180.0}
BELT_GAINS = {"Kp": 38.0, "Ki": 200.0}

RIGS = {
    "BacklashShaft": (SHAFT, SHAFT_GAINS),
    "BacklashBelt": (BELT, BELT_GAINS),
}


def plant_of(model: str, params: dict) -> Plant:
    """The generic plant (docs/model.md §1 table) for an FMU's parameter values."""
    p = {k: v for k, v in params.items() if k not in ("Kp", "Ki")}
    if model == "BacklashShaft":
        return Plant.shaft(**p)
    if model == "BacklashBelt":
        return Plant.belt(**p)
    raise ValueError(f"unknown model {model!r}")


def with_delta(params: dict, delta: float) -> dict:
    return {**params, "Delta": delta}

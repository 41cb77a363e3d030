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

# BacklashWeb with its web decoupled: EA tiny, so that T (from 0, with T_in = v_in = 0) stays
# below 1e-9 N and pulls on the load below 1e-10 of its torques. Its drive train is then BELT,
# which the drive-train tests check it against; the web itself is checked in test_web.py.
WEB_DECOUPLED = {**BELT, "EA": 1e-9}

RIGS = {
    "BacklashShaft": (SHAFT, SHAFT_GAINS),
    "BacklashBelt": (BELT, BELT_GAINS),
    "BacklashWeb": (WEB_DECOUPLED, BELT_GAINS),
}

# The web span's parameters and the tension loop's gains: not part of the drive train.
WEB_ONLY = ("R_w", "L_w", "EA", "v_ref", "Kp_T", "Ki_T")


def plant_of(model: str, params: dict) -> Plant:
    """The generic plant (docs/model.md §1 table) for an FMU's parameter values: a web line's
    drive train alone (its web decoupled, WEB_DECOUPLED)."""
    p = {k: v for k, v in params.items() if k not in ("Kp", "Ki", *WEB_ONLY)}
    if model == "BacklashShaft":
        return Plant.shaft(**p)
    if model in ("BacklashBelt", "BacklashWeb"):
        return Plant.belt(**p)
    raise ValueError(f"unknown model {model!r}")


def with_delta(params: dict, delta: float) -> dict:
    return {**params, "Delta": delta}

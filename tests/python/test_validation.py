"""The packaged FMUs as a tool sees them: fmpy's validator and the interface of docs/model.md §4."""

from __future__ import annotations

import math

import pytest
from fmpy.validation import validate_fmu

COMMON = {
    # name: (causality, type, unit)
    "tau_m": ("input", "Real", "N.m"),
    "tau_L": ("input", "Real", "N.m"),
    "omega_m": ("output", "Real", "rad/s"),
    "omega_L": ("output", "Real", "rad/s"),
    "theta_m": ("output", "Real", "rad"),
    "theta_L": ("output", "Real", "rad"),
    "bound": ("output", "Real", "rad/s"),
    "bound_sup": ("calculatedParameter", "Real", "rad/s"),
    "J_m": ("parameter", "Real", "kg.m2"),
    "J_L": ("parameter", "Real", "kg.m2"),
    "b_m": ("parameter", "Real", "N.m.s/rad"),
    "b_L": ("parameter", "Real", "N.m.s/rad"),
    "Kp": ("parameter", "Real", "N.m.s/rad"),
    "Ki": ("parameter", "Real", "N.m/rad"),
    # 1: Modelica ElastoBacklash, 2: ElastoBacklash2 (docs/model.md §4).
    "contact_law": ("parameter", "Integer", None),
}
# What a drive train of one gap has besides (docs/model.md §4).
SINGLE_GAP = {
    "contact": ("output", "Integer", None),
    "bound_paper": ("output", "Real", "rad/s"),
}
# The interface of each drive train's form and of a web span (docs/model.md §4, §8, §10), named
# by a parameter only that form has.
FORMS = {
    "k": {
        "psi": ("output", "Real", "N.m"),
        "k": ("parameter", "Real", "N.m/rad"),
        "d": ("parameter", "Real", "N.m.s/rad"),
        "Delta": ("parameter", "Real", "rad"),
    },
    "K_b": {
        "psi": ("output", "Real", "N"),
        "K_b": ("parameter", "Real", "N/m"),
        "D_b": ("parameter", "Real", "N.s/m"),
        "R_1": ("parameter", "Real", "m"),
        "R_2": ("parameter", "Real", "m"),
        "R_g1": ("parameter", "Real", "m"),
        "R_g2": ("parameter", "Real", "m"),
        "Delta": ("parameter", "Real", "m"),
    },
}
# A two-stage gearbox (docs/model.md §10): its intermediate shaft and each mesh's interface.
FORMS["k_1"] = {
    "theta_i": ("output", "Real", "rad"),
    "omega_i": ("output", "Real", "rad/s"),
    **{
        name: kind
        for j in (1, 2)
        for name, kind in {
            f"psi_{j}": ("output", "Real", "N.m"),
            f"contact_{j}": ("output", "Integer", None),
            f"n_{j}": ("parameter", "Real", None),
            f"k_{j}": ("parameter", "Real", "N.m/rad"),
            f"Delta_{j}": ("parameter", "Real", "rad"),
            f"d_{j}": ("parameter", "Real", "N.m.s/rad"),
        }.items()
    },
    "J_i": ("parameter", "Real", "kg.m2"),
    "b_i": ("parameter", "Real", "N.m.s/rad"),
}
# A web line (docs/model.md §8): a belt drive's interface and its span's.
FORMS["R_w"] = {
    "v_in": ("input", "Real", "m/s"),
    "T_in": ("input", "Real", "N"),
    "T": ("output", "Real", "N"),
    "bound_T": ("output", "Real", "N"),
    "bound_T_sup": ("calculatedParameter", "Real", "N"),
    "R_w": ("parameter", "Real", "m"),
    "L_w": ("parameter", "Real", "m"),
    "EA": ("parameter", "Real", "N"),
    "v_ref": ("parameter", "Real", "m/s"),
    "Kp_T": ("parameter", "Real", "rad/(s.N)"),
    "Ki_T": ("parameter", "Real", "rad/(s2.N)"),
}
# The forms docs/model.md §4 and §8 give the models it names (a model it does not name is checked
# against the forms its parameters name).
NAMED_FORMS = {
    "BacklashShaft": ["k"],
    "BacklashBelt": ["K_b"],
    "BacklashWeb": ["K_b", "R_w"],
    "BacklashTwoStage": ["k_1"],
}
# SI base-unit exponents (kg, m, s, rad) of every unit the interface uses.
BASE = {
    "N.m": (1, 2, -2, 0),
    "N": (1, 1, -2, 0),
    "rad/s": (0, 0, -1, 1),
    "rad/s2": (0, 0, -2, 1),
    "rad": (0, 0, 0, 1),
    "kg.m2": (1, 2, 0, 0),
    "N.m.s/rad": (1, 2, -1, -1),
    "N.m/rad": (1, 2, -2, -1),
    "N/m": (1, 0, -2, 0),
    "N.s/m": (1, 0, -1, 0),
    "m": (0, 1, 0, 0),
    "m/s": (0, 1, -1, 0),
    "N/s": (1, 1, -3, 0),
    "rad/(s.N)": (-1, -1, 1, 1),
    "rad/(s2.N)": (-1, -1, 0, 1),
}
# Display units users expect (docs/model.md §4): value_display = factor * value_SI.
DISPLAY = {"rad/s": ("rpm", 30.0 / math.pi), "rad": ("deg", 180.0 / math.pi), "m": ("mm", 1000.0)}


def _unit(v):
    return v.unit or (v.declaredType.unit if v.declaredType is not None else None)


def test_fmpy_validation_finds_no_problem(fmu):
    assert validate_fmu(str(fmu.path)) == []


def test_fmu_is_fmi2_cosimulation(fmu):
    assert fmu.md.fmiVersion == "2.0"
    assert fmu.md.coSimulation is not None
    assert fmu.md.coSimulation.modelIdentifier == fmu.path.stem  # the model it was asked for (fmu_path)
    assert fmu.md.coSimulation.canGetAndSetFMUstate and fmu.md.coSimulation.canSerializeFMUstate


def test_interface_names_causalities_and_units(fmu):
    forms = [form for form in FORMS if form in fmu.variables]
    drives = [form for form in forms if form in ("k", "K_b", "k_1")]
    assert len(drives) == 1, f"{fmu.model}: one drive train, shaft, belt or gearbox: {forms}"
    assert "R_w" not in forms or "K_b" in forms, f"{fmu.model}: a web span is pulled by a belt drive"
    assert forms == NAMED_FORMS.get(fmu.model, forms), f"{fmu.model}: {forms}"
    one_gap = {} if "k_1" in forms else SINGLE_GAP
    expected = {**COMMON, **one_gap, **{name: kind for form in forms for name, kind in FORMS[form].items()}}
    for name, (causality, vtype, unit) in expected.items():
        assert name in fmu.variables, f"{fmu.model}: variable {name} missing"
        v = fmu.variables[name]
        assert (v.causality, v.type, _unit(v)) == (causality, vtype, unit), name
        if causality in ("parameter", "calculatedParameter"):
            assert v.variability == "fixed", name


def test_units_are_defined_with_base_units_and_display_units(fmu):
    units = {u.name: u for u in fmu.md.unitDefinitions}
    used = {_unit(v) for v in fmu.md.modelVariables} - {None}
    assert used <= set(units), f"undefined units {used - set(units)}"
    for name in used:
        b = units[name].baseUnit
        assert b is not None, f"unit {name} has no BaseUnit"
        assert (b.kg, b.m, b.s, b.rad) == BASE[name], name
        # factor and offset exact: attributes read back (or their defaults 1 and 0), not computed.
        assert (b.A, b.K, b.mol, b.cd, b.factor, b.offset) == (0, 0, 0, 0, 1.0, 0.0), name
    for name, (display, factor) in DISPLAY.items():
        if name not in used:
            continue
        shown = {d.name: d for d in units[name].displayUnits}
        assert display in shown, f"{name} lacks display unit {display}"
        assert shown[display].factor == pytest.approx(factor, rel=1e-15)
        assert shown[display].offset == 0.0
    # Each FMU has lengths to show in mm only if it has lengths at all: the belt drives do.
    if "K_b" in fmu.variables:
        assert "m" in used

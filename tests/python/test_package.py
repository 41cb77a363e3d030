"""The package backlash_fmu as installed in the venv (the wheel of `cargo xtask wheel` in
`cargo xtask test`, `pip install .` in `cargo xtask pytest`): its design(), its shipped archives,
and the `backlash` command on the venv's PATH.

design() and the `backlash` command run the design library through its Python binding;
`cargo xtask design` runs the same library compiled into the build tool. They are separate
builds of the same arithmetic, so the answers must agree: to 1e-9 relative in every number
(docs: the package's promise), and their JSON text byte for byte.
"""

from __future__ import annotations

import json
import math
import re
import subprocess
import sys
from pathlib import Path

import pytest
from fmpy import read_model_description, simulate_fmu

import backlash_fmu
from test_design import run_design

REPO = Path(__file__).resolve().parents[2]
# The design questions of docs/design-a-drive.md, as (model, keywords, flags).
QUESTIONS = [
    ("shaft", {"accuracy": 0.02}, ["--accuracy", "0.02"]),
    ("belt", {"accuracy": 2.2}, ["--model", "belt", "--accuracy", "2.2"]),
    ("web", {"tension_accuracy": 20.0}, ["--model", "web", "--tension-accuracy", "20"]),
    ("two-stage", {"accuracy": 0.3}, ["--model", "two-stage", "--accuracy", "0.3"]),
]


def backlash_command() -> Path:
    """The `backlash` script pip installed beside the venv's interpreter."""
    return Path(sys.executable).parent / "backlash"


def test_the_package_is_the_installed_one():
    """The suite runs against the package as pip installed it, not the sources in python/."""
    installed = Path(backlash_fmu.__file__).resolve()
    assert "site-packages" in installed.parts, installed
    assert REPO / "python" not in installed.parents


def same_numbers(a, b, path="answer"):
    """a and b have the same structure, strings and None, and numbers equal to 1e-9 relative."""
    assert type(a) is type(b) or {type(a), type(b)} <= {int, float}, (path, a, b)
    if isinstance(a, dict):
        assert list(a) == list(b), path
        for key in a:
            same_numbers(a[key], b[key], f"{path}.{key}")
    elif isinstance(a, list):
        assert len(a) == len(b), path
        for i, (x, y) in enumerate(zip(a, b)):
            same_numbers(x, y, f"{path}[{i}]")
    elif isinstance(a, (int, float)) and not isinstance(a, bool):
        assert math.isclose(a, b, rel_tol=1e-9, abs_tol=0.0), (path, a, b)
    else:
        assert a == b, (path, a, b)


@pytest.mark.parametrize("model, keywords, flags", QUESTIONS, ids=[q[0] for q in QUESTIONS])
def test_design_answers_as_the_command(model, keywords, flags):
    out = run_design(*flags, "--json")
    assert out.returncode == 0, out.stderr
    same_numbers(backlash_fmu.design(model, **keywords), json.loads(out.stdout))


def test_design_takes_parameters_by_their_fmu_names():
    """Keywords by the FMUs' names answer as the flags that set the same values."""
    out = run_design("--model", "belt", "--accuracy", "2.2", "--k", "3e5", "--rg1", "0.02", "--jm", "2e-4", "--json")
    assert out.returncode == 0, out.stderr
    answer = backlash_fmu.design("belt", accuracy=2.2, K_b=3e5, R_g1=0.02, J_m=2e-4)
    same_numbers(answer, json.loads(out.stdout))
    assert (answer["plant"]["K_b"], answer["plant"]["R_g1"], answer["plant"]["J_m"]) == (3e5, 0.02, 2e-4)


@pytest.mark.parametrize(
    "model, keywords, reason",
    [
        ("shaft", {"accuracy": -0.02}, "accuracy = -0.02 must be > 0"),
        ("shaft", {"accuracy": math.nan}, "accuracy = NaN must be finite"),
        ("shaft", {"accuracy": 0.02, "J_m": -2.28}, "J_m = -2.28 must be > 0"),
        ("web", {"tension_accuracy": math.inf}, "tension_accuracy = inf must be finite"),
        ("shaft", {}, "accuracy is required for model shaft"),
        ("shaft", {"accuracy": 0.02, "K_b": 2e5}, "K_b applies to model belt or web only"),
        ("shaft", {"accuracy": 0.02, "stiffness": 200.0}, "unknown parameter `stiffness`"),
        ("shaft", {"accuracy": 0.02, "Kp": 40.0}, "Kp and Ki go together"),
        ("shaft", {"accuracy": "0.02"}, "accuracy = '0.02' is not a number"),
        ("gear", {"accuracy": 0.02}, 'model = "gear"'),
        # Gains that make the loop unstable: no finite bound, so no answer.
        ("shaft", {"accuracy": 0.02, "Kp": -50.0, "Ki": 1.0}, "bound"),
    ],
)
def test_bad_input_raises_value_error_with_the_reason(model, keywords, reason):
    with pytest.raises(ValueError) as refused:
        backlash_fmu.design(model, **keywords)
    assert reason in str(refused.value)


def test_every_archive_is_shipped_and_simulates():
    """Every model of the package's manifest, FMI 2.0 and 3.0: fmpy reads the archive, finds
    the model it is named for, and simulates it (a torque on the motor moves the load)."""
    # The plants the model descriptions define, as the generated FMU reference lists them.
    reference = (REPO / "docs" / "fmu-reference.md").read_text(encoding="utf-8")
    plants = tuple(re.findall(r"^\| \[`(\w+)`\]\(#\w+\) \| plant \|", reference, flags=re.M))
    assert backlash_fmu.MODELS == plants and "BacklashTwoStage" in plants, (backlash_fmu.MODELS, plants)
    for model in backlash_fmu.MODELS:
        for fmi in (2, 3):
            path = backlash_fmu.fmu_path(model, fmi)
            md = read_model_description(str(path))
            assert (md.fmiVersion[0], md.coSimulation.modelIdentifier) == (str(fmi), model)
            result = simulate_fmu(str(path), stop_time=0.5, output_interval=1e-3,
                                  start_values={"tau_m": 1.0}, output=["omega_L", "bound"])
            assert result["time"][-1] == 0.5
            assert result["omega_L"][-1] > 0 and (result["bound"] >= 0).all(), (model, fmi)
    with pytest.raises(ValueError):
        backlash_fmu.fmu_path("BacklashGear")
    with pytest.raises(ValueError):
        backlash_fmu.fmu_path("BacklashShaft", fmi=1)


def test_the_controller_and_the_systems_are_shipped():
    """The controller's archives, and the systems packed with the archives they use, beside the
    package's archives."""
    from backlash_fmu import systems

    assert backlash_fmu.CONTROLLERS == ("BacklashController",)
    for fmi in (2, 3):
        md = read_model_description(str(backlash_fmu.fmu_path("BacklashController", fmi)))
        assert md.coSimulation.modelIdentifier == "BacklashController" and md.modelExchange is None
    shipped = backlash_fmu.fmu.PACKAGED / "systems"
    names = sorted(path.parent.name for path in shipped.glob(f"*/{systems.SSD}"))
    assert names == ["sine", "twin", "web_line"]
    for name in names:
        folder = shipped / name
        system = systems.System.read(folder)
        for c in system.components:
            assert (folder / "resources" / f"{c.model}.fmu").read_bytes() == backlash_fmu.fmu_path(c.model).read_bytes()
        assert (folder.parent / f"{name}.ssp").is_file()


def test_the_backlash_command_answers_as_the_build_tools():
    """The command pip installed prints what `cargo xtask design` prints, byte for byte."""
    for _, _, flags in QUESTIONS:
        ours = subprocess.run([backlash_command(), "design", *flags, "--json"], capture_output=True, text=True)
        theirs = run_design(*flags, "--json")
        assert (ours.returncode, theirs.returncode) == (0, 0), (ours.stderr, theirs.stderr)
        assert ours.stdout == theirs.stdout


@pytest.mark.parametrize("args", [["design", "--accuracy", "-1"], ["design", "--accuracy", "nan"],
                                  ["design"], ["desing"], []])
def test_the_backlash_command_refuses_with_one_line_and_status_2(args):
    out = subprocess.run([backlash_command(), *args], capture_output=True, text=True)
    assert out.returncode == 2, out
    assert out.stdout == ""
    assert out.stderr.startswith("error: ") and out.stderr.count("\n") == 1, out.stderr

"""The reference results every archive carries (FMI-LS-REF, `cargo xtask fmu`): what an importer
finds in extra/org.fmi-standard.fmi-ls-ref/ is a valid manifest naming the two CSV files; a real
importer (fmpy) that replays the inputs' file gets the outputs' file; and the outputs agree with
the independent reference solvers on the same held inputs.

Tolerances:
- fmpy's replay: the same binary, the same calls on the same grid (t_k = start + k h, steps
  t_k+1 - t_k) with the same held inputs (a row at every communication point, which fmpy's
  interpolation w0 v0 + w1 v1 reproduces exactly; each flip a time event there): the same
  arithmetic, so the same bits, the time column aside.
- the controller's outputs against its law written in Python (twin.SampledPi): the same
  operations in the same order on the same doubles (sin from the C library in both), so the same
  bits.
- the independent reference (reference.py, and reference_two_stage.py for the gearbox: DOP853 at
  rtol 1e-13 with located switches; reference_web.py: matrix exponentials with brentq-located switches): 1e-9 relative per signal
  as in test_open_loop.py, over runs whose inputs were chosen so that a difference of 1e-12 in
  them grows at most ~1e3-fold by the end (measured; a drive rattling through its gap under a
  reversing torque would amplify it a billion-fold and no reference could check it).
"""

from __future__ import annotations

import io
import zipfile

import fmpy
import lxml.etree as etree
import numpy as np
import pytest
from backlash_fmu.fmu import fmu_path

import reference
import reference_two_stage
import reference_web
from archives import CONTROLLERS, MODELS, require
from rigs import plant_of
from signals import rel_err

DIR = "extra/org.fmi-standard.fmi-ls-ref"
STATES = ("theta_m", "omega_m", "theta_L", "omega_L")
# reference_two_stage's z: the motor's, the intermediate shaft's and the load's angle and speed.
GEARBOX_STATES = ("theta_m", "omega_m", "theta_i", "omega_i", "theta_L", "omega_L")
# The roles FMI-LS-REF 1.0.0-alpha.1 defines (its table "Role Values").
ROLES = {"document", "requirement", "specification", "model", "parameter", "system", "testcase", "experiment",
         "result", "method", "rationale", "report", "request", "delivery", "configuration", "signature",
         "serialized-state", "meta-data", "other"}


def table(csv: bytes) -> np.ndarray:
    """A CSV file with a header row as a structured array of floats (as fmpy.util.read_csv reads
    a file, for a file inside an archive)."""
    return np.genfromtxt(io.StringIO(csv.decode()), delimiter=",", names=True, dtype=float, deletechars="")


def kit(model: str, fmi: int) -> tuple[etree._Element, np.ndarray, np.ndarray, list[str]]:
    """The manifest, the inputs and outputs (structured arrays) and the archive's entries."""
    with zipfile.ZipFile(fmu_path(model, fmi)) as z:
        names = z.namelist()
        manifest = etree.fromstring(z.read(f"{DIR}/fmi-ls-manifest.xml"))
        inputs, outputs = (table(z.read(f"{DIR}/{model}_{kind}.csv")) for kind in ("in", "out"))
    return manifest, inputs, outputs, names


@pytest.mark.parametrize("fmi", [2, 3])
@pytest.mark.parametrize("model", MODELS + CONTROLLERS)
def test_the_manifest_names_the_files_the_archive_holds(model, fmi):
    manifest, inputs, outputs, names = kit(model, fmi)
    ns = "{http://fmi-standard.org/fmi-ls-manifest}"
    assert manifest.tag == "fmiReferences"
    assert manifest.get(f"{ns}fmi-ls-name") == "org.fmi-standard.fmi-ls-ref"
    assert manifest.get(f"{ns}fmi-ls-version") == "1.0.0-alpha.1"
    assert manifest.get(f"{ns}fmi-ls-description")
    # FMI-LS-REF's <Related>: type, source, role (one of its roles) and description, nothing else.
    for r in manifest.iter("Related"):
        assert set(r.attrib) == {"type", "source", "role", "description"}, r.attrib
        assert r.get("type") == "text/csv" and r.get("description")
        assert r.get("role") in ROLES
    related = {r.get("source"): r.get("role") for r in manifest.iter("Related")}
    assert related == {f"{model}_in.csv": "testcase", f"{model}_out.csv": "result"}
    assert all(f"{DIR}/{source}" in names for source in related)
    md = require(model, fmi).md
    experiment = md.defaultExperiment
    assert inputs["time"][0] == float(experiment.startTime) and inputs["time"][-1] == float(experiment.stopTime)
    assert outputs["time"][0] == float(experiment.startTime)
    assert abs(outputs["time"][-1] - float(experiment.stopTime)) <= 1e-9 * float(experiment.stopTime)
    causality = {v.name: v.causality for v in md.modelVariables}
    assert all(causality[n] == "input" for n in inputs.dtype.names[1:])
    assert all(causality[n] == "output" for n in outputs.dtype.names[1:])
    assert set(outputs.dtype.names[1:]) == {n for n, c in causality.items() if c == "output"}


@pytest.mark.parametrize("fmi", [2, 3])
@pytest.mark.parametrize("model", MODELS + CONTROLLERS)
def test_fmpy_replaying_the_inputs_gets_the_outputs(model, fmi):
    _, inputs, outputs, _ = kit(model, fmi)
    experiment = require(model, fmi).md.defaultExperiment
    h = float(experiment.stepSize)
    result = fmpy.simulate_fmu(
        str(fmu_path(model, fmi)), fmi_type="CoSimulation", input=inputs, output_interval=h,
        output=list(outputs.dtype.names[1:]),
    )
    # fmpy records at every communication point; the outputs' file at every `every`-th.
    every = round((outputs["time"][1] - outputs["time"][0]) / h)
    replay = result[::every]
    assert len(replay) == len(outputs), (len(replay), len(outputs))
    assert np.allclose(replay["time"], outputs["time"], rtol=1e-12, atol=0.0)
    for name in outputs.dtype.names[1:]:
        assert np.array_equal(replay[name], outputs[name]), name


def held(inputs: np.ndarray, names: tuple[str, ...], times: np.ndarray) -> dict[str, np.ndarray]:
    """The value of each input held over the step starting at each of `times`: the inputs' file
    read as an importer reads it (the last row at or before the time: after a flip's pair of
    rows, the new value). Inputs the file does not name are 0, their start value."""
    rows = np.searchsorted(inputs["time"], times, side="right") - 1
    return {n: (inputs[n][rows] if n in inputs.dtype.names else np.zeros(len(times))) for n in names}


@pytest.mark.parametrize("model", MODELS)
def test_the_outputs_agree_with_the_independent_reference(model):
    _, inputs, outputs, _ = kit(model, 2)
    md = require(model, 2).md
    experiment = md.defaultExperiment
    h = float(experiment.stepSize)
    n = round((float(experiment.stopTime) - float(experiment.startTime)) / h)
    every = round((outputs["time"][1] - outputs["time"][0]) / h)
    params = {v.name: float(v.start) for v in md.modelVariables
              if v.causality == "parameter" and v.type == "Real"}
    times = float(experiment.startTime) + np.arange(n) * h
    u = held(inputs, ("tau_m", "tau_L", "v_in", "T_in"), times)
    if model == "BacklashTwoStage":
        # Gearbox.of refuses a damper or friction: the reference solves the undamped plant.
        z, solver = reference_two_stage.run_open_loop(reference_two_stage.Gearbox.of(params), u["tau_m"], u["tau_L"], h)
        expected = {name: z[::every, j] for j, name in enumerate(GEARBOX_STATES)}
    elif model == "BacklashWeb":
        assert params["D_b"] == 0.0, "the references solve the undamped plant"
        table = np.column_stack([u["tau_m"], u["tau_L"], u["v_in"], u["T_in"]])
        ref, solver = reference_web.run_open_loop({k: v for k, v in params.items() if k != "D_b"}, table, h,
                                                  method="expm")
        expected = {name: ref[name][::every] for name in (*STATES, "T")}
    else:
        assert params.get("d", params.get("D_b")) == 0.0, "the references solve the undamped plant"
        params = {k: v for k, v in params.items() if k not in ("d", "D_b")}
        z, _, solver = reference.run_open_loop(plant_of(model, params), u["tau_m"], u["tau_L"], h)
        expected = {name: z[::every, j] for j, name in enumerate(STATES)}
    assert len(solver.switches) >= 20, "the reference experiment must cross the gap again and again"
    errors = {name: rel_err(outputs[name], values) for name, values in expected.items()}
    assert max(errors.values()) <= 1e-9, errors


def test_the_controllers_outputs_are_its_law_one_sample_late():
    """BacklashController's reference run: after step k its torque is the law's sample k of the
    held measured speed, at its own time k h (twin.SampledPi, at the description's start values)."""
    from backlash_fmu import twin

    _, inputs, outputs, _ = kit("BacklashController", 2)
    md = require("BacklashController", 2).md
    start = {v.name: float(v.start) for v in md.modelVariables if v.causality == "parameter"}
    assert start["reference"] == 3
    h = float(md.defaultExperiment.stepSize)
    assert h == start["h"]
    n = round(float(md.defaultExperiment.stopTime) / h)
    every = round((outputs["time"][1] - outputs["time"][0]) / h)
    omega = held(inputs, ("omega_m",), np.arange(n) * h)["omega_m"]
    law = twin.SampledPi(start["Kp"], start["Ki"], twin.references(start["frequency"], start["amplitude"])["sine"], h,
                         kp_t=start["Kp_T"], ki_t=start["Ki_T"], t_ref=start["T_ref"])
    torques = np.array([law.torque(k * h, omega[k]) for k in range(n)])
    assert np.ptp(omega) > 0 and np.ptp(torques) > 1.0
    assert outputs["tau_m"][0] == 0.0
    assert np.array_equal(outputs["tau_m"][1:], torques[every - 1::every])

"""Loading and driving the packaged FMUs with fmpy's FMU2Slave, as an importer would.

FMUs are looked up in $BACKLASH_FMU_DIR, else <repo>/target/fmu (written by `cargo xtask fmu`),
and so is the list of models: the manifest models.txt that `cargo xtask fmu` writes beside the
archives.
"""

from __future__ import annotations

import functools
import os
import shutil
from pathlib import Path

import numpy as np
import pytest
from fmpy import extract, read_model_description
from fmpy.fmi2 import FMU2Slave

REPO = Path(__file__).resolve().parents[2]
STATE_OUTPUTS = ("theta_m", "omega_m", "theta_L", "omega_L")


def fmu_dir() -> Path:
    return Path(os.environ.get("BACKLASH_FMU_DIR", REPO / "target" / "fmu"))


def manifest_path() -> Path:
    """The manifest of the models packaged in fmu_dir(): one model identifier a line."""
    return fmu_dir() / "models.txt"


def _packaged_models() -> tuple[str, ...]:
    """The model identifiers of the manifest, in its order (the packaging's); () when there is
    no manifest: conftest.py then stops the run before any test."""
    try:
        text = manifest_path().read_text()
    except FileNotFoundError:
        return ()
    return tuple(line.strip() for line in text.splitlines() if line.strip())


# Every packaged model, as `cargo xtask fmu` lists them.
MODELS = _packaged_models()


def fmu_path(model: str) -> Path:
    return fmu_dir() / f"{model}.fmu"


class Extracted:
    """One unpacked copy of an FMU and its model description."""

    def __init__(self, model: str):
        self.model = model
        self.path = fmu_path(model)
        if not self.path.is_file():
            raise FileNotFoundError(f"{self.path} not found: run `cargo xtask fmu` first")
        self.md = read_model_description(str(self.path))
        self.unzipdir = extract(str(self.path))
        self.variables = {v.name: v for v in self.md.modelVariables}
        self.vr = {name: v.valueReference for name, v in self.variables.items()}

    def instance(self, name: str = "instance", params: dict | None = None, start_time: float = 0.0) -> "Instance":
        return Instance(self, name, params or {}, start_time)

    def remove(self):
        shutil.rmtree(self.unzipdir, ignore_errors=True)


_extracted: list[Extracted] = []


@functools.cache
def shared(model: str) -> Extracted:
    """The FMU unpacked once per test session."""
    e = Extracted(model)
    _extracted.append(e)
    return e


def separate_copy(model: str) -> Extracted:
    """A second unpacked copy: its shared library is a different file, so the dynamic loader
    gives it its own code and data (a truly fresh instance)."""
    e = Extracted(model)
    _extracted.append(e)
    return e


def require(model: str) -> Extracted:
    """The shared copy of an FMU. A missing FMU fails the test, never skips it (conftest.py already
    stops the run before any test when an archive is missing)."""
    if not fmu_path(model).is_file():
        pytest.fail(f"FMU archive not found: {fmu_path(model)} (build with `cargo xtask fmu`)")
    return shared(model)


def remove_all():
    while _extracted:
        _extracted.pop().remove()


class Instance:
    """An instantiated, initialised co-simulation slave."""

    def __init__(self, fmu: Extracted, name: str, params: dict, start_time: float = 0.0, initialise: bool = True):
        self.fmu, self.vr = fmu, fmu.vr
        self.slave = FMU2Slave(
            guid=fmu.md.guid,
            unzipDirectory=fmu.unzipdir,
            modelIdentifier=fmu.md.coSimulation.modelIdentifier,
            instanceName=name,
        )
        self.slave.instantiate()
        self.params = dict(params)
        self.t0 = start_time
        if initialise:
            self.initialise(start_time)

    def initialise(self, start_time: float = 0.0):
        """Parameters (variability fixed, docs/model.md §4) are set before initialisation."""
        self.t0 = start_time
        self.set(self.params)
        self.slave.setupExperiment(startTime=start_time)
        self.slave.enterInitializationMode()
        self.slave.exitInitializationMode()

    def set(self, values: dict):
        if values:
            self.slave.setReal([self.vr[k] for k in values], [float(v) for v in values.values()])

    def get(self, *names: str) -> list[float]:
        return self.slave.getReal([self.vr[n] for n in names])

    def contact(self) -> int:
        return self.slave.getInteger([self.vr["contact"]])[0]

    def step(self, t: float, h: float, tau_m: float, tau_L: float):
        self.slave.setReal([self.vr["tau_m"], self.vr["tau_L"]], [tau_m, tau_L])
        self.slave.doStep(currentCommunicationPoint=t, communicationStepSize=h)

    def free(self):
        self.slave.terminate()
        self.slave.freeInstance()


class Record:
    """Outputs at the communication points t_0..t_N, one row per point."""

    def __init__(self):
        self.rows: list[list[float]] = []
        self.contact: list[int] = []

    def add(self, inst: Instance):
        self.rows.append(inst.get(*STATE_OUTPUTS, "psi", "bound", "bound_paper"))
        self.contact.append(inst.contact())

    def arrays(self) -> dict[str, np.ndarray]:
        a = np.array(self.rows)
        names = (*STATE_OUTPUTS, "psi", "bound", "bound_paper")
        out = {n: a[:, j] for j, n in enumerate(names)}
        out["z"] = a[:, :4]
        out["contact"] = np.array(self.contact)
        return out


def run_open_loop(inst: Instance, tau_m, tau_L, h: float) -> dict[str, np.ndarray]:
    """Held torques, one per step; outputs at every communication point."""
    rec = Record()
    rec.add(inst)
    for k, (tm, tl) in enumerate(zip(tau_m, tau_L)):
        inst.step(inst.t0 + k * h, h, float(tm), float(tl))
        rec.add(inst)
    return rec.arrays()


def run_pi_loop(inst: Instance, controller, h: float, n: int, w_ref, tau_L) -> dict[str, np.ndarray]:
    """The PI speed loop closed outside the FMU: tau_m from the measured omega_m at each t_k."""
    rec = Record()
    rec.add(inst)
    taus = []
    for k in range(n):
        t = k * h  # time since the start, as in the reference loop
        tau = controller(w_ref(t), inst.get("omega_m")[0])
        taus.append(tau)
        inst.step(inst.t0 + t, h, tau, tau_L(t))
        rec.add(inst)
    out = rec.arrays()
    out["tau_m"] = np.array(taus)
    return out

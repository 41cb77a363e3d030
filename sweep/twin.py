"""The twin closed-loop run on BacklashShaft.fmu through fmpy: one instance with the backlash
(Delta > 0) and its twin without (Delta = 0), each under a PI loop on the motor speed closed
OUTSIDE the FMU and sampled at every communication point (docs/model.md §3):
    e_n = w_ref(t_n) - omega_m(t_n),  tau_m = Kp e_n + Ki x_n,  x_{n+1} = x_n + h e_n.

One definition shared by the demonstration (demo/paper_experiments.py) and the tolerance sweep
(sweep/), so both measure the same thing.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path
from typing import Callable

import numpy as np
from fmpy import extract, read_model_description
from fmpy.fmi2 import FMU2Slave

# Reference amplitude [m/s]: a speed the rig reaches without the spring force exceeding a few N.
SPEED = 0.05


# ------------------------------------------------------------------------------------------
# FMU access
# ------------------------------------------------------------------------------------------


# What the twin run reads of BacklashShaft at every communication point (besides `contact`).
SHAFT_OUTPUTS = ("omega_m", "omega_L", "bound", "bound_paper", "psi")


class Instance:
    """One Co-Simulation instance of an archive's model: `params` (parameters, start values,
    inputs) set before initialization, `outputs` (and `contact`) read together."""

    def __init__(self, unzipdir: str, md, name: str, params: dict[str, float], outputs=SHAFT_OUTPUTS):
        self.vr = {v.name: v.valueReference for v in md.modelVariables}
        self.slave = FMU2Slave(
            guid=md.guid,
            unzipDirectory=unzipdir,
            modelIdentifier=md.coSimulation.modelIdentifier,
            instanceName=name,
        )
        self.slave.instantiate()
        self.slave.setupExperiment(startTime=0.0)
        names = list(params)
        self.slave.setReal([self.vr[n] for n in names], [float(params[n]) for n in names])
        self.slave.enterInitializationMode()
        self.slave.exitInitializationMode()
        self.out_names = list(outputs)
        self.out_vrs = [self.vr[n] for n in self.out_names]
        self.tau_vr = [self.vr["tau_m"]]
        self.contact_vr = [self.vr["contact"]]

    def bound_sup(self) -> float:
        return self.slave.getReal([self.vr["bound_sup"]])[0]

    def get(self, *names: str) -> list[float]:
        return self.slave.getReal([self.vr[n] for n in names])

    def outputs(self) -> dict[str, float]:
        values = self.slave.getReal(self.out_vrs)
        out = dict(zip(self.out_names, values))
        out["contact"] = self.slave.getInteger(self.contact_vr)[0]
        return out

    def step(self, t: float, h: float, tau_m: float) -> None:
        self.slave.setReal(self.tau_vr, [tau_m])
        status = self.slave.doStep(currentCommunicationPoint=t, communicationStepSize=h)
        if status not in (None, 0):
            raise RuntimeError(f"doStep returned status {status} at t = {t}")

    def close(self) -> None:
        self.slave.terminate()
        self.slave.freeInstance()


class Fmu:
    """The archive, extracted once; instances made on demand, each reading `outputs`."""

    def __init__(self, path: Path, outputs=SHAFT_OUTPUTS):
        self.md = read_model_description(str(path))
        self.unzipdir = extract(str(path))
        self.outputs = outputs
        self.count = 0

    def instance(self, params: dict[str, float]) -> Instance:
        self.count += 1
        return Instance(self.unzipdir, self.md, f"i{self.count}", params, self.outputs)


# ------------------------------------------------------------------------------------------
# The twin experiment
# ------------------------------------------------------------------------------------------


@dataclass
class Run:
    t: np.ndarray
    ref: np.ndarray
    omega_m_b: np.ndarray
    omega_L_b: np.ndarray
    omega_m_0: np.ndarray
    omega_L_0: np.ndarray
    tau_b: np.ndarray
    tau_0: np.ndarray
    bound: np.ndarray
    bound_paper: np.ndarray
    contact: np.ndarray
    bound_sup: float

    @property
    def deviation(self) -> np.ndarray:
        return np.abs(self.omega_L_b - self.omega_L_0)


def twin_run(
    fmu: Fmu,
    plant: dict[str, float],
    delta: float,
    kp: float,
    ki: float,
    ref: Callable[[float], float],
    horizon: float,
    h: float,
) -> Run:
    """The PI loop closed on each of two instances (Delta and Delta = 0), from rest."""
    common = dict(plant, Kp=kp, Ki=ki)
    with_b = fmu.instance(dict(common, Delta=delta))
    without = fmu.instance(dict(common, Delta=0.0))
    try:
        n = int(round(horizon / h))
        cols = {k: np.zeros(n + 1) for k in ("ref", "wmb", "wLb", "wm0", "wL0", "taub", "tau0", "b", "bp")}
        contact = np.zeros(n + 1, dtype=int)
        x_b = x_0 = 0.0  # controller integrator states
        for i in range(n + 1):
            t = i * h
            ob, o0 = with_b.outputs(), without.outputs()
            r = ref(t)
            e_b, e_0 = r - ob["omega_m"], r - o0["omega_m"]
            tau_b, tau_0 = kp * e_b + ki * x_b, kp * e_0 + ki * x_0
            cols["ref"][i], cols["wmb"][i], cols["wLb"][i] = r, ob["omega_m"], ob["omega_L"]
            cols["wm0"][i], cols["wL0"][i] = o0["omega_m"], o0["omega_L"]
            cols["taub"][i], cols["tau0"][i] = tau_b, tau_0
            cols["b"][i], cols["bp"][i] = ob["bound"], ob["bound_paper"]
            contact[i] = ob["contact"]
            if i == n:
                break
            with_b.step(t, h, tau_b)
            without.step(t, h, tau_0)
            x_b += h * e_b
            x_0 += h * e_0
        sup = with_b.bound_sup()
    finally:
        with_b.close()
        without.close()
    return Run(
        t=np.arange(n + 1) * h,
        ref=cols["ref"],
        omega_m_b=cols["wmb"],
        omega_L_b=cols["wLb"],
        omega_m_0=cols["wm0"],
        omega_L_0=cols["wL0"],
        tau_b=cols["taub"],
        tau_0=cols["tau0"],
        bound=cols["b"],
        bound_paper=cols["bp"],
        contact=contact,
        bound_sup=sup,
    )


def reference_frequency(poles) -> float:
    """The reversing reference's frequency [Hz]: the closed-loop poles' mean natural frequency,
    where h oscillates, so that the deviation comes close to the true bound. `poles` as
    `cargo xtask design --json` lists them, [re, im] pairs."""
    return float(np.mean([math.hypot(re, im) for re, im in poles])) / (2 * math.pi)


def references(f_ref: float, amplitude: float = SPEED) -> dict[str, Callable[[float], float]]:
    return {
        "step": lambda t: amplitude,
        "sine": lambda t: amplitude * math.sin(2.0 * math.pi * f_ref * t),
    }


def sample_row(fmu: Fmu, index: int, params: dict[str, float], settings: dict[str, float]) -> dict:
    """One sample of a sweep: the twin run at these parameters under the sine reference, reduced
    to what the table records. Pure: the same inputs give the same row, bit for bit."""
    plant = {name: params[name] for name in ("J_m", "J_L", "b_m", "b_L", "k")}
    amplitude, frequency = settings["amplitude"], settings["frequency"]
    run = twin_run(fmu, plant, params["Delta"], params["Kp"], params["Ki"],
                   references(frequency, amplitude)["sine"], settings["horizon"], settings["h"])
    max_dev = float(run.deviation.max())
    bound_sup = float(run.bound_sup)
    return {
        "sample": index,
        **params,
        "max_dev": max_dev,
        "bound_sup": bound_sup,
        "ratio": max_dev / bound_sup if bound_sup > 0 else (0.0 if max_dev == 0 else math.inf),
        "meets": max_dev <= settings["accuracy"],
    }


def _process_cache():
    """Per-process store of unpacked archives. Lives in sys.modules because this module may be
    shipped by value to Dask workers, and each shipped task then gets fresh module globals."""
    import sys
    import threading
    import types

    store = types.ModuleType("_backlash_sweep_archives")
    store.fmus, store.lock = {}, threading.Lock()
    return sys.modules.setdefault(store.__name__, store)


def fmu_from_bytes(data: bytes) -> Fmu:
    """The archive given as bytes, written and unpacked once per process (keyed by its hash)."""
    import atexit
    import hashlib
    import shutil
    import tempfile

    store = _process_cache()
    digest = hashlib.sha256(data).hexdigest()
    with store.lock:
        fmu = store.fmus.get(digest)
        if fmu is None:
            folder = tempfile.mkdtemp(prefix="backlash-sweep-")
            path = Path(folder) / "BacklashShaft.fmu"
            path.write_bytes(data)
            fmu = Fmu(path)
            atexit.register(shutil.rmtree, folder, True)
            atexit.register(shutil.rmtree, fmu.unzipdir, True)
            store.fmus[digest] = fmu
    return fmu


def prepare(fmu_bytes: bytes) -> None:
    """The one-time work of a process before its first sample: imports, unpacking, and loading
    the model's shared library (one instance made and freed)."""
    fmu_from_bytes(fmu_bytes).instance({"Delta": 0.0}).close()


def sweep_task(fmu_bytes: bytes, index: int, params: dict[str, float], settings: dict[str, float]):
    """One sample as a task: (row, address of the Dask worker that ran it, or "local")."""
    row = sample_row(fmu_from_bytes(fmu_bytes), index, params, settings)
    try:
        from distributed import get_worker

        where = get_worker().address
    except (ImportError, ValueError):
        where = "local"
    return row, where

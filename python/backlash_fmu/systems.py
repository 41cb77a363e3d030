"""The co-simulation systems packed beside the archives (`systems/<name>/`: SystemStructure.ssd
with its parameter sets and FMUs, OspSystemStructure.xml; `systems/<name>.ssp` zipped), run in
real masters and closed here in Python under a master's timing (docs/model.md §9).

- `System.read(folder)`: its components (name, model, the values of its parameter set), its
  connections, its communication step h and its stop time, as the SSD states them (h in the Open
  Simulation Platform's annotation on its DefaultExperiment, the form libcosim reads);
- `python_loop(system, times, sizes)`: the loop closed here, as a master that passes values after
  each step (Jacobi) does it: every plant through `backlash_fmu.fmu`, every BacklashController
  replaced by `twin.SampledPi` with its parameters, holding each sample's torque until the end of
  the next step; step k from times[k] by sizes[k];
- `run_ecos`, `run_libcosim`, `run_fmpy`: the masters (PyPI ecospy, libcosimpy, fmpy), each
  returning the times and sizes of its steps and the outputs after each step. libcosim takes h
  from the packed .ssp itself; ecos (`step_size`) and fmpy's runner (`step_size`, `stop_time`)
  are given the SSD's.

A run's record maps (component, output) to the output's values after steps 1..N.

    from backlash_fmu import systems
    folder = systems.system_dir("sine")
    run = systems.run_ecos(folder, steps=8000)
    ref = systems.python_loop(systems.System.read(folder), run.times, run.sizes)
"""

from __future__ import annotations

import ctypes
import shutil
import sys
import tempfile
import xml.etree.ElementTree as ET
from dataclasses import dataclass
from pathlib import Path
from typing import Callable

import numpy as np

from . import fmu
from .twin import SampledPi, references, trapezoid

SSD = "SystemStructure.ssd"
OSP = "OspSystemStructure.xml"
NS = {
    "ssd": "http://ssp-standard.org/SSP1/SystemStructureDescription",
    "ssc": "http://ssp-standard.org/SSP1/SystemStructureCommon",
    "ssv": "http://ssp-standard.org/SSP1/SystemStructureParameterValues",
    "osp": "http://opensimulationplatform.com/SSP/OSPAnnotations",
}
# Where the SSD states its communication step: the Open Simulation Platform's annotation on its
# DefaultExperiment, as libcosim's SSP parser reads it (src/cosim/ssp/ssp_parser.cpp).
STEP_PATH = ("ssd:DefaultExperiment/ssd:Annotations/ssc:Annotation[@type='com.opensimulationplatform']"
             "/osp:Algorithm/osp:FixedStepAlgorithm")
CONTROLLER = "BacklashController"
# The controller's reference kinds, by the value of its `reference` parameter.
STEP, TRAPEZOID, SINE = 1, 2, 3
# libcosim's clock: integer nanoseconds.
NANOSECONDS = 1_000_000_000


def system_dir(name: str) -> Path:
    """The packed system `name` (sine, twin, web_line) beside the archives."""
    return fmu.archive_dir() / "systems" / name


@dataclass
class Component:
    name: str
    model: str
    params: dict[str, float]
    # Its connectors: (name, kind) with kind "input" or "output".
    connectors: list[tuple[str, str]]


@dataclass
class System:
    folder: Path
    components: list[Component]
    # (start component, start connector, end component, end connector)
    connections: list[tuple[str, str, str, str]]
    stop_time: float
    # The communication step h (every controller's sample period: it refuses any other step).
    step_size: float

    @classmethod
    def read(cls, folder: Path) -> "System":
        """The system of `folder`/SystemStructure.ssd, each component's parameters those of the
        parameter set it binds."""
        root = ET.parse(folder / SSD).getroot()
        components = []
        for c in root.iterfind("ssd:System/ssd:Elements/ssd:Component", NS):
            params: dict[str, float] = {}
            for binding in c.iterfind("ssd:ParameterBindings/ssd:ParameterBinding", NS):
                params.update(parameter_set(folder / binding.get("source")))
            connectors = [(k.get("name"), k.get("kind")) for k in c.iterfind("ssd:Connectors/ssd:Connector", NS)]
            components.append(Component(c.get("name"), Path(c.get("source")).stem, params, connectors))
        connections = [(c.get("startElement"), c.get("startConnector"), c.get("endElement"), c.get("endConnector"))
                       for c in root.iterfind("ssd:System/ssd:Connections/ssd:Connection", NS)]
        stop = float(root.find("ssd:DefaultExperiment", NS).get("stopTime"))
        return cls(folder, components, connections, stop, stated_step(root, folder / SSD))

    @classmethod
    def read_packed(cls, ssp: Path) -> "System":
        """The system of the zipped `ssp`, read from a copy unpacked for the purpose (its
        `folder` is gone afterwards: `python_loop` needs the unpacked folder)."""
        with tempfile.TemporaryDirectory() as tmp:
            shutil.unpack_archive(str(ssp), tmp, format="zip")
            return cls.read(Path(tmp))

    @classmethod
    def read_any(cls, path: Path) -> "System":
        """`read` for a folder, `read_packed` for a zipped .ssp."""
        return cls.read_packed(path) if Path(path).is_file() else cls.read(path)

    @property
    def steps(self) -> int:
        """The steps of h to the stop time."""
        return int(round(self.stop_time / self.step_size))

    def outputs(self) -> list[tuple[str, str]]:
        """Every output connector, (component, output), in the order of the file."""
        return [(c.name, n) for c in self.components for n, kind in c.connectors if kind == "output"]


def stated_step(root: ET.Element, where: Path) -> float:
    """The communication step the SSD `root` (of the file `where`) states: `baseStepSize` of
    ssd:DefaultExperiment/ssd:Annotations/ssc:Annotation[type=com.opensimulationplatform]/
    osp:Algorithm/osp:FixedStepAlgorithm."""
    found = root.findall(STEP_PATH, NS)
    if len(found) != 1:
        raise ValueError(f"{where}: {len(found)} osp:FixedStepAlgorithm annotations on DefaultExperiment, not one")
    return float(found[0].get("baseStepSize"))


def parameter_set(path: Path) -> dict[str, float]:
    """The values of the SSP parameter set (.ssv) `path`, by parameter name (an Integer as a
    float, as the controller's `reference`)."""
    root = ET.parse(path).getroot()
    values = {}
    for p in root.iterfind("ssv:Parameters/ssv:Parameter", NS):
        (value,) = list(p)
        values[p.get("name")] = float(value.get("value"))
    return values


def controller_parameters(archive: Path, given: dict[str, float]) -> dict[str, float]:
    """Every parameter of the BacklashController `archive`: the values `given`, the others at their
    start values in its modelDescription.xml."""
    from fmpy import read_model_description

    md = read_model_description(str(archive))
    starts = {v.name: float(v.start) for v in md.modelVariables if v.causality == "parameter"}
    unknown = set(given) - set(starts)
    if unknown:
        raise ValueError(f"{archive}: no parameters {sorted(unknown)}")
    return {**starts, **given}


def controller_reference(p: dict[str, float]) -> Callable[[float], float]:
    """The speed reference r(t) of a BacklashController with the parameters `p` (all of them, as
    `controller_parameters` gives them)."""
    kind = int(p["reference"])
    if kind == STEP:
        return references(0.0, p["amplitude"])["step"]
    if kind == TRAPEZOID:
        return trapezoid(p["amplitude"], p["t_ramp"], p["t_hold"])
    if kind == SINE:
        return references(p["frequency"], p["amplitude"])["sine"]
    raise ValueError(f"reference = {kind}: choose 1 (step), 2 (trapezoid) or 3 (sine)")


@dataclass
class Run:
    """A run of N steps: step k starts at times[k] with the size sizes[k]; record[(component,
    output)] holds the output after each step."""

    times: list[float]
    sizes: list[float]
    record: dict[tuple[str, str], np.ndarray]


def python_loop(system: System, times: list[float], sizes: list[float]) -> Run:
    """The system's loop closed here under a Jacobi master's timing: before step k every input
    takes the value its source output had after step k-1 (before the first: the outputs after
    initialization); plants step from times[k] by sizes[k], each controller takes its sample k at
    its own time k h and outputs that sample's torque after the step (before the first step
    ends: tau_m's start value, 0)."""
    archives = {}
    plants, pis = {}, {}
    try:
        for c in system.components:
            if c.model == CONTROLLER:
                p = controller_parameters(system.folder / "resources" / f"{CONTROLLER}.fmu", c.params)
                pis[c.name] = SampledPi(p["Kp"], p["Ki"], controller_reference(p), p["h"],
                                        kp_t=p["Kp_T"], ki_t=p["Ki_T"], t_ref=p["T_ref"])
            else:
                if c.model not in archives:
                    archives[c.model] = fmu.Archive(system.folder / "resources" / f"{c.model}.fmu")
                plants[c.name] = archives[c.model].co_simulation(c.name, c.params)
        outputs = system.outputs()
        # tau_m's start value (0): no system sets it (test_masters.py).
        held = {name: 0.0 for name in pis}

        def read() -> dict[tuple[str, str], float]:
            values = {}
            for comp, name in outputs:
                values[comp, name] = held[comp] if comp in pis else plants[comp].get(name)[0]
            return values

        now = read()
        rows = []
        for k, (t, h) in enumerate(zip(times, sizes)):
            inputs: dict[str, dict[str, float]] = {c.name: {} for c in system.components}
            for a, out, b, inp in system.connections:
                inputs[b][inp] = now[a, out]
            for name, plant in plants.items():
                plant.step(t, h, **inputs[name])
            for name, pi in pis.items():
                held[name] = pi.torque(k * pi.h, inputs[name].get("omega_m", 0.0), inputs[name].get("T", 0.0))
            now = read()
            rows.append([now[key] for key in outputs])
    finally:
        for plant in plants.values():
            plant.free()
        for archive in archives.values():
            archive.remove()
    table = np.array(rows)
    return Run(list(times), list(sizes), {key: table[:, i] for i, key in enumerate(outputs)})


def _load_tbb() -> None:
    """ecos's library needs libtbb.so.12: the venv's (PyPI tbb), loaded globally first, so that
    no system package is needed."""
    ctypes.CDLL(str(Path(sys.prefix) / "lib" / "libtbb.so.12"), mode=ctypes.RTLD_GLOBAL)


def run_ecos(path: Path, steps: int | None = None) -> Run:
    """The system of `path` (a system folder or its zipped .ssp) in ecos (SSP): every component's
    parameter set applied (ecos applies the sets named "values"), `steps` steps of h (default: to
    the stop time). ecos reads no step from the SSD: its `step_size` is required, here the SSD's
    h. ecos counts time as t += h and hands every step h."""
    _load_tbb()
    from ecospy import EcosLib, EcosSimulation

    system = System.read_any(path)
    steps = system.steps if steps is None else steps
    h = system.step_size
    EcosLib.set_log_level("warn")
    outputs = system.outputs()
    rows, times = [], [0.0]
    with EcosSimulation(ssp_path=str(path), step_size=h) as sim:
        sim.init(parameter_set="values")
        for _ in range(steps):
            times.append(sim.step())
            rows.append([sim.get_real(f"{c}::{n}") for c, n in outputs])
        sim.terminate()
    table = np.array(rows)
    return Run(times[:-1], [h] * steps, {key: table[:, i] for i, key in enumerate(outputs)})


def run_libcosim(path: Path, steps: int | None = None) -> Run:
    """The system in libcosim, `steps` steps of its base step (default: until its clock reaches
    the SSD's stop time): `path` a system folder (its OspSystemStructure.xml, the step its
    BaseStepSize) or its zipped .ssp (libcosim's SSP loader, CosimExecution.from_ssp_file, given
    no step: libcosim takes it from the SSD's annotation). libcosim counts time in integer
    nanoseconds and hands every step the difference of two such times in seconds."""
    from libcosimpy.CosimExecution import CosimExecution
    from libcosimpy.CosimLogging import CosimLogLevel, log_output_level
    from libcosimpy.CosimObserver import CosimObserver

    system = System.read_any(path)
    stop = round(system.stop_time * NANOSECONDS)
    log_output_level(CosimLogLevel.ERROR)
    if Path(path).is_file():
        execution = CosimExecution.from_ssp_file(str(path))
    else:
        execution = CosimExecution.from_osp_config_file(str(Path(path) / OSP))
    index = {s.name.decode(): s.index for s in execution.slave_infos()}
    vr = {(name, v.name.decode()): v.reference for name, i in index.items() for v in execution.slave_variables(i)}
    last = CosimObserver.create_last_value()
    execution.add_observer(last)
    outputs = system.outputs()
    rows, nanoseconds = [], [0]
    while (nanoseconds[-1] < stop) if steps is None else (len(rows) < steps):
        if not execution.step(1):
            raise RuntimeError(f"libcosim refused a step at t = {nanoseconds[-1]} ns")
        nanoseconds.append(execution.status().current_time)
        rows.append([last.last_real_values(index[c], [vr[c, n]])[0] for c, n in outputs])
    seconds = [t / NANOSECONDS for t in nanoseconds]
    table = np.array(rows)
    return Run(seconds[:-1], [b - a for a, b in zip(seconds, seconds[1:])],
               {key: table[:, i] for i, key in enumerate(outputs)})


def fmpy_parameters(system: System):
    """The system's own parameter sets as one fmpy ParameterSet, each value named
    component.parameter (fmpy's runner reads the bindings but applies only the set it is given)."""
    from fmpy.ssp.ssd import Parameter, ParameterSet

    return ParameterSet(parameters=[
        Parameter(name=f"{c.name}.{n}", type="Integer" if n == "reference" else "Real", value=v)
        for c in system.components for n, v in c.params.items()])


def run_fmpy(ssp: Path, steps: int | None = None) -> Run:
    """The zipped system `ssp` in fmpy's SSP runner, `steps` steps of h. The runner reads neither
    the step nor the stop time from the SSD (without them it runs to 1 s in steps of 1/100 of
    the stop time): both are given, h the SSD's. It steps while its clock (t += h) is short of
    the stop time, so the stop time given is half a step before the last point. It applies only
    the parameter set it is given, so the file's own sets are given as one (`fmpy_parameters`).
    It passes 0 to every input before the first step."""
    from fmpy.ssp.simulation import simulate_ssp

    system = System.read_packed(ssp)
    steps = system.steps if steps is None else steps
    h = system.step_size
    result = simulate_ssp(str(ssp), start_time=0.0, stop_time=steps * h - h / 2, step_size=h,
                          parameter_set=fmpy_parameters(system))
    return Run([float(t) for t in result["time"]], [h] * len(result),
               {(c, n): np.asarray(result[f"{c}.{n}"], dtype=float) for c, n in system.outputs()})

"""The shipped systems (systems/, packed beside the archives by `cargo xtask fmu`) in real
co-simulation masters: (a) `sine`, the paper's sine experiment on BacklashShaft; (b) `twin`, twin
drives with and without backlash under the same reference; (c) `web_line`, the web line under
the speed and tension PI. Each master is given the zipped .ssp (SSP 1.0): ecos, libcosim (PyPI
libcosimpy, its SSP loader) and fmpy's SSP runner (which does not apply the files' parameter
bindings itself: backlash_fmu.systems.run_fmpy hands it the files' own sets); libcosim also runs
the OSP file (OspSystemStructure.xml) of the unpacked folder.

Where the communication step h comes from: the SSD states it in the Open Simulation Platform's
annotation on ssd:DefaultExperiment (osp:FixedStepAlgorithm baseStepSize), equal to the OSP file's
BaseStepSize and to every controller's sample period (checked). libcosim's SSP loader reads it
(no step is passed); ecos reads no step from an SSD and needs `step_size` (it runs on at another
step, its controller refusing every step: checked); fmpy's runner reads neither step nor stop
time and needs `step_size` and `stop_time` (without them its step is refused: checked). Both are
given the SSD's h.

What is checked, against the loop closed here in Python (backlash_fmu.systems.python_loop: the
plants through the same archives, each BacklashController replaced by twin.SampledPi, the PI law
written a second time):
- every master passes values after each step (Jacobi): before step k an input takes its source
  output after step k-1; the controller's torque of the sample at t_k is out after that step,
  so the drive receives it over [t_(k+1), t_(k+2)). ecos and libcosim pass the outputs after
  initialization before the first step, fmpy's runner passes 0: every system starts at rest, so
  both are 0 (checked);
- ecos and fmpy count time as t += h and hand every step h; libcosim counts integer nanoseconds
  and hands every step the difference of two such times in seconds, h being the OSP file's
  BaseStepSize (checked for every master). The loop here is given each master's times and sizes,
  so the values agree to the bit;
- the masters agree with one another: ecos and fmpy to the bit (the same timing), libcosim from
  the .ssp with libcosim from the OSP file to the bit, libcosim with ecos to 1e-12 of each
  output's largest magnitude (its steps differ from h by round-off);
- the files say what they claim: the OSP file is the SSD's system with the same values, and the
  gains and frequency are the design answer's.
libcosim refuses FMI 3.0 archives ("Unsupported FMI version", its own limit, libcosim 0.11); ecos
runs them, and runs (a) with them here; fmpy's SSP runner looks for FMI 2.0's binaries/linux64
only.
"""

from __future__ import annotations

import ctypes
import shutil
import xml.etree.ElementTree as ET

import numpy as np
import pytest
from backlash_fmu import design, systems, twin
from backlash_fmu.fmu import fmu_path

SYSTEMS = ("sine", "twin", "web_line")
# Each master's run: "libcosim" from the OSP file, the others from the zipped .ssp alone.
MASTERS = ("ecos", "libcosim", "libcosim_ssp", "fmpy")
OSP_NS = {"osp": "http://opensimulationplatform.com/MSMI/OSPSystemStructure"}
# How far libcosim's run may stray from ecos's, relative to each output's largest magnitude:
# measured 2e-14 (sine, twin) and 7e-14 (web line) over the whole horizon.
MASTERS_AGREE = 1e-12


@pytest.fixture(scope="module")
def runs() -> dict:
    """Each master's run of each system it runs, and the Python loop under that master's
    timing; computed once."""
    out = {}
    for name in SYSTEMS:
        folder = systems.system_dir(name)
        ssp = folder.parent / f"{name}.ssp"
        system = systems.System.read(folder)
        out[name, "ecos"] = systems.run_ecos(ssp)
        out[name, "libcosim"] = systems.run_libcosim(folder)
        out[name, "libcosim_ssp"] = systems.run_libcosim(ssp)
        out[name, "fmpy"] = systems.run_fmpy(ssp)
        for master in MASTERS:
            run = out[name, master]
            out[name, master, "python"] = systems.python_loop(system, run.times, run.sizes)
    return out


def clock_sum(h: float, n: int) -> list[float]:
    """t_0 = 0, t_k+1 = t_k + h: ecos's and fmpy's clock."""
    times = [0.0]
    for _ in range(n - 1):
        times.append(times[-1] + h)
    return times


def osp_step(folder) -> float:
    """The OSP file's BaseStepSize."""
    return float(ET.parse(folder / systems.OSP).getroot().find("osp:BaseStepSize", OSP_NS).text)


@pytest.mark.parametrize("name", SYSTEMS)
@pytest.mark.parametrize("master", MASTERS)
def test_a_master_runs_the_shipped_system_as_the_loop_closed_here(runs, name, master):
    """Every master's run, of h the OSP file's BaseStepSize to the SSD's stop time, equal to the
    bit to the loop closed here under its timing."""
    folder = systems.system_dir(name)
    system = systems.System.read(folder)
    run, here = runs[name, master], runs[name, master, "python"]
    h = osp_step(folder)
    n = round(system.stop_time / h)
    assert len(run.times) == n
    if master.startswith("libcosim"):
        h_ns = round(h * systems.NANOSECONDS)
        assert run.times == [k * h_ns / systems.NANOSECONDS for k in range(n)]
        assert run.sizes == [(k + 1) * h_ns / systems.NANOSECONDS - k * h_ns / systems.NANOSECONDS
                             for k in range(n)]
    else:
        assert run.times == clock_sum(h, n) and run.sizes == [h] * n
    assert set(run.record) == set(system.outputs())
    for key, values in run.record.items():
        assert np.ptp(values) > 0, f"{key} must move"
        assert np.array_equal(values, here.record[key]), f"{name} in {master}: {key}"


@pytest.mark.parametrize("name", SYSTEMS)
def test_the_masters_agree_with_one_another(runs, name):
    ecos, libcosim = runs[name, "ecos"], runs[name, "libcosim"]
    for key, values in ecos.record.items():
        scale = np.max(np.abs(values))
        assert np.max(np.abs(libcosim.record[key] - values)) <= MASTERS_AGREE * scale, key
        assert np.array_equal(runs[name, "fmpy"].record[key], values), key
        assert np.array_equal(runs[name, "libcosim_ssp"].record[key], libcosim.record[key]), key
    assert runs[name, "libcosim_ssp"].times == libcosim.times


def test_the_ssd_states_the_osp_files_step_where_libcosim_reads_it():
    """The SSD's communication step, in the nesting libcosim's SSP parser reads
    (ssd:DefaultExperiment/ssd:Annotations/ssc:Annotation of type com.opensimulationplatform/
    osp:Algorithm/osp:FixedStepAlgorithm, attribute baseStepSize; src/cosim/ssp/ssp_parser.cpp),
    is the OSP file's BaseStepSize and every controller's sample period h; in the folder and in
    the zipped .ssp alike."""
    import zipfile

    ns = {"ssd": "http://ssp-standard.org/SSP1/SystemStructureDescription",
          "ssc": "http://ssp-standard.org/SSP1/SystemStructureCommon",
          "osp": "http://opensimulationplatform.com/SSP/OSPAnnotations"}
    for name in SYSTEMS:
        folder = systems.system_dir(name)
        text = (folder / systems.SSD).read_bytes()
        with zipfile.ZipFile(folder.parent / f"{name}.ssp") as ssp:
            assert ssp.read(systems.SSD) == text, name
        experiment = ET.fromstring(text).find("ssd:DefaultExperiment", ns)
        annotations = [a for a in experiment.iterfind("ssd:Annotations/ssc:Annotation", ns)
                       if a.get("type") == "com.opensimulationplatform"]
        assert len(annotations) == 1, name
        (algorithm,) = annotations[0].iterfind("osp:Algorithm/osp:FixedStepAlgorithm", ns)
        h = float(algorithm.get("baseStepSize"))
        assert h == osp_step(folder), name
        system = systems.System.read(folder)
        assert system.step_size == h, name
        periods = [c.params["h"] for c in system.components if c.model == systems.CONTROLLER]
        assert periods and all(p == h for p in periods), (name, periods)


def test_ecos_takes_the_step_as_an_argument_only(runs, capfd):
    """ecos's SSP loader reads no step from the SSD (src/ecos/ssp/ssp_loader.cpp: of the
    DefaultExperiment's annotations only its own scenario type), so EcosSimulation's `step_size`
    has no default; given a step other than the file's it runs on, BacklashController refusing
    every step (ecos does not check fmi2DoStep's status; it logs the FMUs' messages at debug
    level), and the drive never moves."""
    import inspect

    systems._load_tbb()
    from ecospy import EcosLib, EcosSimulation

    assert inspect.signature(EcosSimulation).parameters["step_size"].default is inspect.Parameter.empty
    folder = systems.system_dir("sine")
    h, steps = osp_step(folder), 100
    EcosLib.set_log_level("debug")
    try:
        with EcosSimulation(ssp_path=str(folder.parent / "sine.ssp"), step_size=2 * h) as sim:
            sim.init(parameter_set="values")
            moved = []
            for _ in range(steps):
                sim.step()
                moved.append([sim.get_real("controller::tau_m"), sim.get_real("plant::omega_m")])
            sim.terminate()
    finally:
        EcosLib.set_log_level("warn")
    assert f"communicationStepSize {2 * h} is not the sample period" in capfd.readouterr().out
    assert not np.any(moved)
    right = runs["sine", "ecos"].record
    assert np.any(right["controller", "tau_m"][:steps]) and np.any(right["plant", "omega_m"][:steps])


@pytest.mark.parametrize("name", SYSTEMS)
def test_fmpy_takes_the_step_and_stop_time_as_arguments_only(name, capfd):
    """fmpy's SSP runner reads neither the step nor the stop time from the SSD
    (fmpy/ssp/simulation.py, simulate_ssp: stop_time 1 and step_size stop_time / 100 by default;
    fmpy/ssp/ssd.py, read_ssd, does not read DefaultExperiment): given neither, its first step is
    refused by BacklashController."""
    from fmpy.fmi1 import FMICallException
    from fmpy.ssp.simulation import simulate_ssp

    folder = systems.system_dir(name)
    assert osp_step(folder) != 1 / 100
    with pytest.raises(FMICallException, match="fmi2DoStep"):
        simulate_ssp(str(folder.parent / f"{name}.ssp"),
                     parameter_set=systems.fmpy_parameters(systems.System.read(folder)))
    assert f"communicationStepSize {1 / 100} is not the sample period" in capfd.readouterr().out


def test_every_system_starts_at_rest_so_the_masters_first_inputs_agree():
    """ecos and libcosim pass the outputs after initialization before the first step, fmpy's
    runner passes 0: the same when every connected output starts at 0 (the controllers' tau_m,
    the plants' omega_m and T, start values of their descriptions that no parameter set changes)."""
    from fmpy import read_model_description

    for name in SYSTEMS:
        system = systems.System.read(systems.system_dir(name))
        sources = {(a, out) for a, out, _, _ in system.connections}
        for c in system.components:
            md = read_model_description(str(system.folder / "resources" / f"{c.model}.fmu"))
            starts = {v.name: float(v.start) for v in md.modelVariables if v.start is not None}
            for component, output in sources:
                if component == c.name:
                    assert c.params.get(output, starts[output]) == 0.0, (name, component, output)


def test_ecos_runs_the_sine_system_with_the_fmi3_archives_alike(runs, tmp_path):
    """The same system with FMI 3.0 archives under resources/: ecos runs it to the same values."""
    folder = tmp_path / "sine"
    shutil.copytree(systems.system_dir("sine"), folder)
    for model in ("BacklashShaft", "BacklashController"):
        shutil.copy(fmu_path(model, 3), folder / "resources" / f"{model}.fmu")
    fmi3 = systems.run_ecos(folder)
    for key, values in runs["sine", "ecos"].record.items():
        assert np.array_equal(fmi3.record[key], values), key


def test_the_osp_files_are_the_ssd_systems_with_the_same_values():
    for name in SYSTEMS:
        folder = systems.system_dir(name)
        system = systems.System.read(folder)
        ns = {"osp": "http://opensimulationplatform.com/MSMI/OSPSystemStructure"}
        root = ET.parse(folder / systems.OSP).getroot()
        simulators = {}
        for s in root.iterfind("osp:Simulators/osp:Simulator", ns):
            values = {v.get("variable"): float(list(v)[0].get("value"))
                      for v in s.iterfind("osp:InitialValues/osp:InitialValue", ns)}
            simulators[s.get("name")] = (s.get("source"), values)
        assert simulators == {c.name: (f"resources/{c.model}.fmu", c.params) for c in system.components}, name
        connections = [tuple(x for v in c.iterfind("osp:Variable", ns) for x in (v.get("simulator"), v.get("name")))
                       for c in root.iterfind("osp:Connections/osp:VariableConnection", ns)]
        assert connections == system.connections, name
        assert float(root.find("osp:BaseStepSize", ns).text) == system.step_size, name


def test_the_shipped_gains_are_the_design_answers():
    """The sine systems' gains and reference frequency are the design answer for the paper's rig
    (the demonstration's, backlash_fmu.demo.shaft_design); the web line's speed gains its design
    answer, its tension loop the web-line demonstration's."""
    from backlash_fmu.demo import DEMO_ACCURACY, DEMO_DELTA, DEMO_TENSION_ACCURACY

    shaft = design("shaft", accuracy=DEMO_ACCURACY, Delta=DEMO_DELTA)
    sine = systems.System.read(systems.system_dir("sine"))
    params = {c.name: c.params for c in sine.components}
    assert params["controller"]["Kp"] == shaft["Kp"] and params["controller"]["Ki"] == shaft["Ki"]
    assert params["plant"]["Kp"] == shaft["Kp"] and params["plant"]["Delta"] == DEMO_DELTA
    assert params["controller"]["frequency"] == twin.reference_frequency(shaft["poles"])
    assert params["controller"]["amplitude"] == twin.SPEED
    # BacklashController's defaults are this experiment's.
    from fmpy import read_model_description

    md = read_model_description(str(fmu_path(systems.CONTROLLER)))
    start = {v.name: float(v.start) for v in md.modelVariables if v.causality == "parameter"}
    for name, value in params["controller"].items():
        assert start[name] == value, name
    web = design("web", tension_accuracy=DEMO_TENSION_ACCURACY)
    line = {c.name: c.params for c in systems.System.read(systems.system_dir("web_line")).components}
    assert line["controller"]["Kp"] == web["Kp"] and line["controller"]["Ki"] == web["Ki"]
    assert (line["controller"]["Kp_T"], line["controller"]["Ki_T"], line["controller"]["T_ref"]) == (
        twin.KP_T, twin.KI_T, twin.T_REF)
    assert (line["controller"]["amplitude"], line["controller"]["frequency"]) == (
        twin.SPEED_AMPLITUDE, twin.SPEED_FREQUENCY)
    # The line's bounds are those of its controller's loops.
    for gain in ("Kp", "Ki", "Kp_T", "Ki_T"):
        assert line["line"][gain] == line["controller"][gain], gain


def test_libcosim_refuses_fmi3_with_its_own_reason(tmp_path):
    """libcosim 0.11 reads FMI 1.0 and 2.0 only: our FMI 3.0 archive is refused by version, before
    anything of ours is loaded."""
    from libcosimpy.CosimLogging import CosimLogLevel, log_output_level
    from libcosimpy.CosimSlave import CosimLocalSlave
    from libcosimpy._internal import libcosimc

    shutil.copy(fmu_path("BacklashShaft", 3), tmp_path / "BacklashShaft.fmu")
    log_output_level(CosimLogLevel.FATAL)
    slave = CosimLocalSlave(fmu_path=str(tmp_path / "BacklashShaft.fmu"), instance_name="plant")
    get_error = libcosimc().cosim_last_error_message
    get_error.restype = ctypes.c_char_p
    assert not slave.ptr(), "libcosim 0.11 loaded an FMI 3.0 archive"
    assert b"Unsupported FMI version" in get_error()

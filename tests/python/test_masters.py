"""The archives in real co-simulation masters: ecos (PyPI ecospy) and fmpy's SSP runner from an
SSP 1.0 system, and libcosim (PyPI libcosimpy) from an OSP system structure, each running two BacklashShaft
components of ONE archive file: a plant under a constant motor torque, and a follower whose motor
torque is the plant's motor speed (1 N.m per rad/s), through a connection.

What is checked, against a loop closed here through the same archive (backlash_fmu.fmu):
- every master transfers values Jacobi-style: over the step [t_k, t_k+1) the follower's input is
  the plant's output at t_k; before the first step ecos and libcosim pass the plant's initial
  output to the follower (in Initialization Mode), fmpy's SSP runner passes 0;
- ecos and fmpy count time as a sum of steps (t += h) and hand each fmi2DoStep the step size h
  as given; libcosim counts integer nanoseconds and hands each fmi2DoStep the difference of two such
  times in seconds (k h_ns / 1e9): the loop here does each master's arithmetic, so the values
  agree to the bit;
- two components of one archive file: ecos closes and reopens the library for the second one,
  which the library survives (it stays loaded, tests/python/test_reload.py); libcosim loads the
  file once, fmpy unpacks it once per component.
libcosim refuses FMI 3.0 archives ("Unsupported FMI version", its own limit, libcosim 0.11); ecos
runs them, and does here; fmpy's SSP runner looks for FMI 2.0's binaries/linux64 only.
"""

from __future__ import annotations

import ctypes
import shutil
import sys
import zipfile
from pathlib import Path

import numpy as np
import pytest
from backlash_fmu.fmu import fmu_path

from archives import shared

# ecos's library needs libtbb.so.12: the venv's (PyPI tbb), loaded first and globally, so that
# no system package is needed.
ctypes.CDLL(str(Path(sys.prefix) / "lib" / "libtbb.so.12"), mode=ctypes.RTLD_GLOBAL)

from ecospy import EcosLib, EcosSimulation  # noqa: E402
from libcosimpy.CosimExecution import CosimExecution  # noqa: E402
from libcosimpy.CosimLogging import CosimLogLevel, log_output_level  # noqa: E402
from libcosimpy.CosimObserver import CosimObserver  # noqa: E402

H = 0.01
STEPS = 300
NS = 1_000_000_000
PLANT = {"tau_m": 10.0, "omega_m": 0.5, "Delta": 0.001}
FOLLOWER = {"J_m": 1.0}


def reference(fmi: int, times: list[float], sizes: list[float], first: float | None = None) -> np.ndarray:
    """(plant omega_m, follower tau_m, follower omega_m) after each step, the loop closed here:
    the follower's input over [t_k, t_k+1) is the plant's output at t_k, but over the first step
    `first` if given; step k starts at times[k] with the size sizes[k]."""
    archive = shared("BacklashShaft", fmi)
    plant = archive.co_simulation("plant", PLANT)
    follower = archive.co_simulation("follower", {**FOLLOWER, "tau_m": plant.get("omega_m")[0]})
    rows = []
    try:
        for k in range(STEPS):
            w = first if k == 0 and first is not None else plant.get("omega_m")[0]
            follower.set_inputs(tau_m=w)
            plant.step(times[k], sizes[k])
            follower.step(times[k], sizes[k])
            rows.append((plant.get("omega_m")[0], w, follower.get("omega_m")[0]))
    finally:
        plant.free()
        follower.free()
    return np.array(rows)


def ssp_system(folder: Path, archive: Path) -> Path:
    """An SSP 1.0 system folder: both components of `archive`, copied once to resources/."""
    (folder / "resources").mkdir(parents=True)
    shutil.copy(archive, folder / "resources" / "BacklashShaft.fmu")

    def values(params: dict) -> str:
        return "".join(f'<ssv:Parameter name="{n}"><ssv:Real value="{v!r}"/></ssv:Parameter>' for n, v in params.items())

    def component(name: str, params: dict, connectors: str) -> str:
        return f"""
      <ssd:Component name="{name}" source="resources/BacklashShaft.fmu">
        <ssd:Connectors>{connectors}</ssd:Connectors>
        <ssd:ParameterBindings><ssd:ParameterBinding><ssd:ParameterValues>
          <ssv:ParameterSet version="1.0" name="values"><ssv:Parameters>{values(params)}</ssv:Parameters></ssv:ParameterSet>
        </ssd:ParameterValues></ssd:ParameterBinding></ssd:ParameterBindings>
      </ssd:Component>"""

    output = '<ssd:Connector name="omega_m" kind="output"><ssc:Real/></ssd:Connector>'
    inputs = '<ssd:Connector name="tau_m" kind="input"><ssc:Real/></ssd:Connector>'
    (folder / "SystemStructure.ssd").write_text(f"""<?xml version="1.0" encoding="UTF-8"?>
<ssd:SystemStructureDescription xmlns:ssc="http://ssp-standard.org/SSP1/SystemStructureCommon"
    xmlns:ssd="http://ssp-standard.org/SSP1/SystemStructureDescription"
    xmlns:ssv="http://ssp-standard.org/SSP1/SystemStructureParameterValues" name="pair" version="1.0">
  <ssd:System name="pair">
    <ssd:Elements>{component("plant", PLANT, output)}{component("follower", FOLLOWER, inputs + output)}
    </ssd:Elements>
    <ssd:Connections>
      <ssd:Connection startElement="plant" startConnector="omega_m" endElement="follower" endConnector="tau_m"/>
    </ssd:Connections>
  </ssd:System>
</ssd:SystemStructureDescription>
""")
    return folder


@pytest.mark.parametrize("fmi", [2, 3])
def test_ecos_runs_two_components_of_one_archive_jacobi(fmi, tmp_path):
    system = ssp_system(tmp_path / "system", fmu_path("BacklashShaft", fmi))
    EcosLib.set_log_level("warn")
    rows, times = [], [0.0]
    with EcosSimulation(ssp_path=str(system), step_size=H) as sim:
        sim.init(parameter_set="values")
        for _ in range(STEPS):
            times.append(sim.step())
            rows.append((sim.get_real("plant::omega_m"), 0.0, sim.get_real("follower::omega_m")))
        sim.terminate()
    ran = np.array(rows)
    # ecos's clock: t += h.
    clock = [0.0]
    for _ in range(STEPS):
        clock.append(clock[-1] + H)
    assert times == clock
    expected = reference(fmi, times, [H] * STEPS)
    assert np.ptp(expected[:, 2]) > 0.1, "the follower must move"
    assert np.array_equal(ran[:, 0], expected[:, 0]) and np.array_equal(ran[:, 2], expected[:, 2])


def test_libcosim_runs_two_components_of_one_archive_jacobi(tmp_path):
    (tmp_path / "fmus").mkdir()
    shutil.copy(fmu_path("BacklashShaft", 2), tmp_path / "fmus" / "BacklashShaft.fmu")

    def initial(params: dict) -> str:
        return "".join(f'<InitialValue variable="{n}"><Real value="{v!r}"/></InitialValue>' for n, v in params.items())

    osp = tmp_path / "OspSystemStructure.xml"
    osp.write_text(f"""<?xml version="1.0" encoding="utf-8" ?>
<OspSystemStructure xmlns="http://opensimulationplatform.com/MSMI/OSPSystemStructure" version="0.1">
  <StartTime>0.0</StartTime>
  <BaseStepSize>{H!r}</BaseStepSize>
  <Algorithm>fixedStep</Algorithm>
  <Simulators>
    <Simulator name="plant" source="fmus/BacklashShaft.fmu"><InitialValues>{initial(PLANT)}</InitialValues></Simulator>
    <Simulator name="follower" source="fmus/BacklashShaft.fmu"><InitialValues>{initial(FOLLOWER)}</InitialValues></Simulator>
  </Simulators>
  <Connections>
    <VariableConnection><Variable simulator="plant" name="omega_m"/><Variable simulator="follower" name="tau_m"/></VariableConnection>
  </Connections>
</OspSystemStructure>
""")
    log_output_level(CosimLogLevel.ERROR)
    execution = CosimExecution.from_osp_config_file(str(osp))
    index = {s.name.decode(): s.index for s in execution.slave_infos()}
    vr = {(name, v.name.decode()): v.reference for name, i in index.items() for v in execution.slave_variables(i)}
    last = CosimObserver.create_last_value()
    execution.add_observer(last)
    rows, nanoseconds = [], [0]
    for _ in range(STEPS):
        assert execution.step(1)
        nanoseconds.append(execution.status().current_time)
        plant = last.last_real_values(index["plant"], [vr["plant", "omega_m"]])[0]
        follower = last.last_real_values(index["follower"], [vr["follower", "omega_m"]])[0]
        rows.append((plant, 0.0, follower))
    ran = np.array(rows)
    h_ns = round(H * NS)
    assert nanoseconds == [k * h_ns for k in range(STEPS + 1)]
    seconds = [t / NS for t in nanoseconds]
    expected = reference(2, seconds, [b - a for a, b in zip(seconds, seconds[1:])])
    assert np.ptp(expected[:, 2]) > 0.1, "the follower must move"
    assert np.array_equal(ran[:, 0], expected[:, 0]) and np.array_equal(ran[:, 2], expected[:, 2])


def test_libcosim_refuses_fmi3_with_its_own_reason(tmp_path):
    """libcosim 0.11 reads FMI 1.0 and 2.0 only: our FMI 3.0 archive is refused by version, before
    anything of ours is loaded."""
    from libcosimpy.CosimSlave import CosimLocalSlave

    shutil.copy(fmu_path("BacklashShaft", 3), tmp_path / "BacklashShaft.fmu")
    log_output_level(CosimLogLevel.FATAL)
    slave = CosimLocalSlave(fmu_path=str(tmp_path / "BacklashShaft.fmu"), instance_name="plant")
    from libcosimpy._internal import libcosimc

    get_error = libcosimc().cosim_last_error_message
    get_error.restype = ctypes.c_char_p
    assert not slave.ptr(), "libcosim 0.11 loaded an FMI 3.0 archive"
    assert b"Unsupported FMI version" in get_error()


def test_fmpy_ssp_runner_runs_two_components_of_one_archive_jacobi(tmp_path):
    """fmpy's SSP runner reads a zipped .ssp; it applies no parameter binding of the file, only the
    `parameter_set` it is given (component.variable), and records each row at the start time of
    its step with the values after it. It steps while its clock (t += h) is short of the stop
    time, so a stop time half a step before the last point gives exactly STEPS steps."""
    from fmpy.ssp.ssd import Parameter, ParameterSet
    from fmpy.ssp.simulation import simulate_ssp

    system = ssp_system(tmp_path / "system", fmu_path("BacklashShaft", 2))
    ssp = tmp_path / "pair.ssp"
    with zipfile.ZipFile(ssp, "w") as z:
        for path in sorted(system.rglob("*")):
            if path.is_file():
                z.write(path, path.relative_to(system).as_posix())
    values = ParameterSet(parameters=[Parameter(name=f"{c}.{n}", type="Real", value=v)
                                      for c, params in (("plant", PLANT), ("follower", FOLLOWER))
                                      for n, v in params.items()])
    result = simulate_ssp(str(ssp), start_time=0.0, stop_time=STEPS * H - H / 2, step_size=H, parameter_set=values)
    assert len(result) == STEPS
    clock = [0.0]
    for _ in range(STEPS - 1):
        clock.append(clock[-1] + H)
    assert list(result["time"]) == clock
    expected = reference(2, clock, [H] * STEPS, first=0.0)
    assert np.ptp(expected[:, 2]) > 0.1, "the follower must move"
    assert np.array_equal(result["plant.omega_m"], expected[:, 0])
    assert np.array_equal(result["follower.omega_m"], expected[:, 2])

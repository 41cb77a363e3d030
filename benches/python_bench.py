"""Python side of `cargo xtask bench`: the PI loop through fmpy, the same loop in scipy, and
fmpy's simulate_fmu as Model Exchange (CVode) beside Co-Simulation.

Prints one line per result, `@ <key> <value> [<value> ...]`, which xtask/src/bench.rs collects
into BENCHMARKS.md. The archive is driven through the package's driver, backlash_fmu.fmu
(fmpy's FMU2Slave); BacklashShaft.fmu of $BACKLASH_FMU_DIR when that is set, else the package's
own. Reuses the test suite's independent solver and rig (tests/python, loaded by path: test
code, not part of the package): reference.py (solve_ivp with event location, restarted at every
communication step and every switch), rigs.py (the shaft rig and its PI gains), signals.py.

The loop (also run natively by benches/native_host.c `piloop`): sampled PI on omega_m
(reference.SampledPI), speed reference 5 sin(2 pi 0.5 t) rad/s, load torque -2 N.m from
t = 4 s, h = 1 ms, BacklashShaft with rigs.SHAFT (Delta = 2.69 mm) and rigs.SHAFT_GAINS.
"""

from __future__ import annotations

import argparse
import importlib.util
import os
import statistics
import sys
import time
from pathlib import Path
from types import ModuleType

# 4x4 products by the thousand: BLAS worker threads only add synchronisation (see conftest.py).
for _var in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

import numpy as np  # noqa: E402
from backlash_fmu import fmu  # noqa: E402

TESTS = Path(__file__).resolve().parents[1] / "tests" / "python"


def test_helper(name: str) -> ModuleType:
    """The test suite's module tests/python/`name`.py, loaded by its path under its own name
    (the helpers import each other by those names), once."""
    if name not in sys.modules:
        spec = importlib.util.spec_from_file_location(name, TESTS / f"{name}.py")
        assert spec is not None and spec.loader is not None
        module = importlib.util.module_from_spec(spec)
        sys.modules[name] = module
        spec.loader.exec_module(module)
    return sys.modules[name]


reference = test_helper("reference")
rigs = test_helper("rigs")
signals = test_helper("signals")
SHAFT, SHAFT_GAINS, plant_of = rigs.SHAFT, rigs.SHAFT_GAINS, rigs.plant_of
rel_err, sine_reference = signals.rel_err, signals.sine_reference

H = 1e-3
MODEL = "BacklashShaft"
W_REF = sine_reference(5.0, 0.5)


def tau_load(t: float) -> float:
    return -2.0 if t >= 4.0 else 0.0


def emit(key: str, *values: object) -> None:
    print("@", key, *values, flush=True)


def quartiles(samples: list[float]) -> tuple[float, float, float]:
    q1, med, q3 = statistics.quantiles(samples, n=4, method="inclusive")
    return med, q1, q3


def fmpy_loop(archive: fmu.Archive, n: int, instrumented: bool) -> tuple[float, float, float | None]:
    """One run of the loop as a user writes it with the package's driver; returns (wall s of the
    loop, CPU s of the loop, wall s inside the driver's calls or None)."""
    inst = archive.co_simulation(name="bench", params={**SHAFT, **SHAFT_GAINS})
    pi = reference.SampledPI(SHAFT_GAINS["Kp"], SHAFT_GAINS["Ki"], H)
    clock = time.perf_counter
    inside = 0.0
    try:
        start, start_cpu = clock(), time.process_time()
        if instrumented:
            for k in range(n):
                t = k * H
                a = clock()
                w = inst.get("omega_m")[0]
                b = clock()
                tau = pi(W_REF(t), w)
                c = clock()
                inst.step(t, H, tau_m=tau, tau_L=tau_load(t))
                inside += (b - a) + (clock() - c)
        else:
            for k in range(n):
                t = k * H
                tau = pi(W_REF(t), inst.get("omega_m")[0])
                inst.step(t, H, tau_m=tau, tau_L=tau_load(t))
        total, total_cpu = clock() - start, time.process_time() - start_cpu
    finally:
        inst.free()
    return total, total_cpu, (inside if instrumented else None)


def bench_fmpy(archive: fmu.Archive, seconds: float, repeats: int) -> None:
    n = round(seconds / H)
    runs = [fmpy_loop(archive, n, False) for _ in range(repeats)]
    wall = [r[0] / n * 1e6 for r in runs]
    cpu = [r[1] / n * 1e6 for r in runs]
    # CPU time (time.process_time) first, then wall-clock time, as the native host prints them.
    emit("fmpy_loop_us", *quartiles(cpu), *quartiles(wall), n, repeats)
    shares, inside_us = [], []
    for _ in range(repeats):
        total, _cpu, inside = fmpy_loop(archive, n, True)
        shares.append(inside / total)
        inside_us.append(inside / n * 1e6)
    emit("fmpy_inside_calls_share", *quartiles(shares))
    emit("fmpy_inside_calls_us", *quartiles(inside_us))


def trajectory_fmu(archive: fmu.Archive, n: int) -> np.ndarray:
    """States at t_0..t_N of the loop through fmpy (untimed, for the accuracy comparison)."""
    inst = archive.co_simulation(name="accuracy", params={**SHAFT, **SHAFT_GAINS})
    try:
        pi = reference.SampledPI(SHAFT_GAINS["Kp"], SHAFT_GAINS["Ki"], H)
        rows = [inst.get(*fmu.STATES)]
        for k in range(n):
            t = k * H
            tau = pi(W_REF(t), inst.get("omega_m")[0])
            inst.step(inst.t0 + t, H, tau_m=tau, tau_L=tau_load(t))
            rows.append(inst.get(*fmu.STATES))
    finally:
        inst.free()
    return np.array(rows)


def trajectory_scipy(n: int, method: str, rtol: float, atol: float) -> tuple[np.ndarray, float, int, float]:
    plant = plant_of(MODEL, SHAFT)
    start, start_cpu = time.perf_counter(), time.process_time()
    z, _u, _taus, ref = reference.run_pi_loop(
        plant, SHAFT_GAINS["Kp"], SHAFT_GAINS["Ki"], H, n, W_REF, tau_load, method=method, rtol=rtol, atol=atol
    )
    return z, time.perf_counter() - start, len(ref.switches), time.process_time() - start_cpu


def state_error(z: np.ndarray, z_ref: np.ndarray) -> float:
    """Largest relative error (signals.rel_err) among the four states over the whole run."""
    return max(rel_err(z[:, j], z_ref[:, j]) for j in range(4))


def bench_scipy(archive: fmu.Archive, seconds: float, settings: list[tuple[str, float]]) -> None:
    n = round(seconds / H)
    # The shared reference: reference.py's own setting (DOP853, rtol 1e-13, atol 1e-17).
    z_ref, wall, switches, _cpu = trajectory_scipy(n, "DOP853", 1e-13, 1e-17)
    emit("reference_run", seconds, wall, switches)
    # Its own error level: the same loop with Radau at the same tolerances.
    z_radau, *_ = trajectory_scipy(n, "Radau", 1e-13, 1e-17)
    emit("reference_radau_diff", state_error(z_radau, z_ref))

    z_fmu = trajectory_fmu(archive, n)
    emit("fmu_error", state_error(z_fmu, z_ref), f"{z_fmu[-1, 0]:.17g}", f"{z_fmu[-1, 1]:.17g}",
         f"{z_fmu[-1, 2]:.17g}", f"{z_fmu[-1, 3]:.17g}", n)
    for method, rtol in settings:
        # atol scaled like reference.py's (u is ~1e-3 rad, so atol must sit well below rtol).
        z, wall, switches, cpu = trajectory_scipy(n, method, rtol, rtol * 1e-4)
        emit("scipy", method, rtol, rtol * 1e-4, state_error(z, z_ref), seconds / cpu, switches, seconds / wall)


def bench_simulate(seconds: float, repeats: int) -> None:
    """fmpy's own simulate_fmu over the rig, as Model Exchange (CVode, fmpy's default solver,
    locating the contact switches with the FMU's event indicators) and as Co-Simulation (h = 1 ms):
    wall time of each run and the largest difference of omega_L between the two at the output
    points. Open loop, motor torque 1.5 sin(2 pi 0.5 t) N.m (fmpy interpolates it linearly between
    its 1 ms samples in Model Exchange and holds it over each step in Co-Simulation)."""
    import fmpy

    path = str(fmu.fmu_path(MODEL))
    t = np.arange(0.0, seconds + H / 2, H)
    signal = np.array(list(zip(t, 1.5 * np.sin(np.pi * t), np.zeros_like(t))),
                      dtype=[("time", np.float64), ("tau_m", np.float64), ("tau_L", np.float64)])
    common = dict(start_time=0.0, stop_time=seconds, output_interval=H, input=signal,
                  start_values={**SHAFT, **SHAFT_GAINS}, output=["omega_L", "contact"])
    runs = {}
    for name, kw in [("me", dict(fmi_type="ModelExchange", solver="CVode", relative_tolerance=1e-8)),
                     ("cs", dict(fmi_type="CoSimulation", step_size=H))]:
        walls = []
        for _ in range(repeats):
            start = time.perf_counter()
            result = fmpy.simulate_fmu(path, **common, **kw)
            walls.append(time.perf_counter() - start)
        runs[name] = result
        switches = int(np.count_nonzero(np.diff(result["contact"])))
        emit(f"simulate_{name}_s", *quartiles(walls), seconds, repeats, switches)
    # Model Exchange records the event instants too: compare at the output grid only, where a time
    # recorded twice (an event on the grid) counts with its later value.
    me, cs = runs["me"], runs["cs"]
    k = np.round(me["time"] / H)
    on_grid = np.abs(me["time"] / H - k) < 1e-6
    last = {int(i): w for i, w in zip(k[on_grid], me["omega_L"][on_grid])}
    grid = np.round(cs["time"] / H).astype(int)
    if not all(i in last for i in grid):
        raise SystemExit("simulate_fmu: the Model Exchange run misses output points of the Co-Simulation run")
    diff = np.max(np.abs(np.array([last[i] for i in grid]) - cs["omega_L"]))
    emit("simulate_me_cs_diff", diff, np.max(np.abs(cs["omega_L"])))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--loop-seconds", type=float, default=20.0, help="simulated time of the fmpy loop")
    parser.add_argument("--repeats", type=int, default=7, help="repetitions of the fmpy loop")
    parser.add_argument("--scipy-seconds", type=float, default=3.0, help="simulated time of the accuracy runs")
    parser.add_argument("--simulate-seconds", type=float, default=20.0, help="simulated time of the simulate_fmu runs")
    parser.add_argument(
        "--sweep",
        default="RK45:1e-3,RK45:1e-6,RK45:1e-9,RK45:1e-12,DOP853:1e-3,DOP853:1e-8,DOP853:1e-12",
        help="scipy settings, method:rtol, comma-separated (RK45 is solve_ivp's default)",
    )
    args = parser.parse_args()

    with fmu.Archive.of(MODEL) as archive:
        bench_fmpy(archive, args.loop_seconds, args.repeats)
        bench_scipy(archive, args.scipy_seconds,
                    [(m, float(r)) for m, r in (x.split(":") for x in args.sweep.split(","))])
        bench_simulate(args.simulate_seconds, min(args.repeats, 3))


if __name__ == "__main__":
    main()

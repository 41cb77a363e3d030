"""Python side of `cargo xtask bench`: the PI loop through fmpy, the same loop in scipy, and
fmpy's simulate_fmu as Model Exchange (CVode) beside Co-Simulation.

Prints one line per result, `@ <key> <value> [<value> ...]`, which xtask/src/bench.rs collects
into BENCHMARKS.md. Reuses the test suite's independent solver and drivers (tests/python):
reference.py (solve_ivp with event location, restarted at every communication step and every
switch), fmu_driver.py (fmpy's FMU2Slave), rigs.py (the shaft rig and its PI gains).

The loop (also run natively by benches/native_host.c `piloop`): sampled PI on omega_m
(reference.SampledPI), speed reference 5 sin(2 pi 0.5 t) rad/s, load torque -2 N.m from
t = 4 s, h = 1 ms, BacklashShaft with rigs.SHAFT (Delta = 2.69 mm) and rigs.SHAFT_GAINS.
"""

from __future__ import annotations

import argparse
import os
import statistics
import sys
import time
from pathlib import Path

# 4x4 products by the thousand: BLAS worker threads only add synchronisation (see conftest.py).
for _var in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests" / "python"))

import numpy as np  # noqa: E402

import fmu_driver  # noqa: E402
import reference  # noqa: E402
from rigs import SHAFT, SHAFT_GAINS, plant_of  # noqa: E402
from signals import rel_err, sine_reference  # noqa: E402

H = 1e-3
MODEL = "BacklashShaft"
W_REF = sine_reference(5.0, 0.5)


def tau_load(t: float) -> float:
    return -2.0 if t >= 4.0 else 0.0


def emit(key: str, *values) -> None:
    print("@", key, *values, flush=True)


def quartiles(samples):
    q1, med, q3 = statistics.quantiles(samples, n=4, method="inclusive")
    return med, q1, q3


def fmpy_loop(fmu: fmu_driver.Extracted, n: int, instrumented: bool):
    """One run of the loop as a user writes it with the test suite's fmpy helpers; returns
    (wall s of the loop, CPU s of the loop, wall s inside the fmpy calls or None)."""
    inst = fmu.instance("bench", {**SHAFT, **SHAFT_GAINS})
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
                inst.step(t, H, tau, tau_load(t))
                inside += (b - a) + (clock() - c)
        else:
            for k in range(n):
                t = k * H
                tau = pi(W_REF(t), inst.get("omega_m")[0])
                inst.step(t, H, tau, tau_load(t))
        total, total_cpu = clock() - start, time.process_time() - start_cpu
    finally:
        inst.free()
    return total, total_cpu, (inside if instrumented else None)


def bench_fmpy(fmu, seconds: float, repeats: int) -> None:
    n = round(seconds / H)
    runs = [fmpy_loop(fmu, n, False) for _ in range(repeats)]
    wall = [r[0] / n * 1e6 for r in runs]
    cpu = [r[1] / n * 1e6 for r in runs]
    # CPU time (time.process_time) first, then wall-clock time, as the native host prints them.
    emit("fmpy_loop_us", *quartiles(cpu), *quartiles(wall), n, repeats)
    shares, inside_us = [], []
    for _ in range(repeats):
        total, _cpu, inside = fmpy_loop(fmu, n, True)
        shares.append(inside / total)
        inside_us.append(inside / n * 1e6)
    emit("fmpy_inside_calls_share", *quartiles(shares))
    emit("fmpy_inside_calls_us", *quartiles(inside_us))


def trajectory_fmu(fmu, n: int) -> np.ndarray:
    """States at t_0..t_N of the loop through fmpy (untimed, for the accuracy comparison)."""
    inst = fmu.instance("accuracy", {**SHAFT, **SHAFT_GAINS})
    try:
        pi = reference.SampledPI(SHAFT_GAINS["Kp"], SHAFT_GAINS["Ki"], H)
        out = fmu_driver.run_pi_loop(inst, pi, H, n, W_REF, tau_load)
    finally:
        inst.free()
    return out["z"]


def trajectory_scipy(n: int, method: str, rtol: float, atol: float):
    plant = plant_of(MODEL, SHAFT)
    start, start_cpu = time.perf_counter(), time.process_time()
    z, _u, _taus, ref = reference.run_pi_loop(
        plant, SHAFT_GAINS["Kp"], SHAFT_GAINS["Ki"], H, n, W_REF, tau_load, method=method, rtol=rtol, atol=atol
    )
    return z, time.perf_counter() - start, len(ref.switches), time.process_time() - start_cpu


def state_error(z: np.ndarray, z_ref: np.ndarray) -> float:
    """Largest relative error (signals.rel_err) among the four states over the whole run."""
    return max(rel_err(z[:, j], z_ref[:, j]) for j in range(4))


def bench_scipy(fmu, seconds: float, settings: list[tuple[str, float]]) -> None:
    n = round(seconds / H)
    # The shared reference: reference.py's own setting (DOP853, rtol 1e-13, atol 1e-17).
    z_ref, wall, switches, _cpu = trajectory_scipy(n, "DOP853", 1e-13, 1e-17)
    emit("reference_run", seconds, wall, switches)
    # Its own error level: the same loop with Radau at the same tolerances.
    z_radau, *_ = trajectory_scipy(n, "Radau", 1e-13, 1e-17)
    emit("reference_radau_diff", state_error(z_radau, z_ref))

    z_fmu = trajectory_fmu(fmu, n)
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

    path = str(fmu_driver.fmu_path(MODEL))
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

    fmu = fmu_driver.Extracted(MODEL)
    try:
        bench_fmpy(fmu, args.loop_seconds, args.repeats)
        bench_scipy(fmu, args.scipy_seconds, [(m, float(r)) for m, r in (x.split(":") for x in args.sweep.split(","))])
        bench_simulate(args.simulate_seconds, min(args.repeats, 3))
    finally:
        fmu.remove()


if __name__ == "__main__":
    main()

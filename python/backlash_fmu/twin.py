"""The twin closed-loop runs: two Co-Simulation instances of one archive side by side, one with
the backlash (Delta > 0) and its twin without (Delta = 0), each under loops closed OUTSIDE the FMU
and sampled at every communication point (step h, zero-order hold on the motor torque).

- `twin_run`: a shaft or belt drive (BacklashShaft, BacklashBelt) under a PI loop on the motor
  speed (docs/model.md §3):
      e_n = w_ref(t_n) - omega_m(t_n),  tau_m = Kp e_n + Ki x_n,  x_{n+1} = x_n + h e_n;
- `twin_web_run`: a web line (BacklashWeb) under that speed PI and an outer tension PI that
  trims its reference (docs/model.md §8):
      e_T,n = T_ref - T(t_n),  w_ref,n = w_ref0(t_n) + Kp_T e_T,n + Ki_T x_T,n,  x_T,n+1 = x_T,n + h e_T,n
      e_n = w_ref,n - omega_m(t_n),  tau_m = Kp e_n + Ki x_c,n,  x_c,n+1 = x_c,n + h e_n;
- `sample_row`, `sample_rows`, `prepare`, `archive_from_bytes`, `unpacked`: one sample (or a
  chunk of samples) of a tolerance sweep (backlash_fmu.sweep) of any model it sweeps (shaft,
  belt, web), on an archive sent as bytes and unpacked once per process.

One definition shared by the demonstration (backlash_fmu.demo) and the tolerance sweep, so that
both measure the same thing; every instance is driven through backlash_fmu.fmu.

    from backlash_fmu import fmu, twin
    with fmu.Archive.of("BacklashShaft") as archive:
        run = twin.twin_run(archive, plant, 1e-3, kp, ki, twin.references(1.4)["sine"], 1.5, 1e-3)
    print(run.deviation.max(), run.bound_sup)
"""

from __future__ import annotations

import atexit
import hashlib
import math
import shutil
import tempfile
import threading
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Callable, Iterable

import numpy as np

from . import fmu

# Reference amplitude [m/s]: a speed the rig reaches without the spring force exceeding a few N.
SPEED = 0.05

# What the twin run reads of a drive at every communication point (besides `contact`).
SHAFT_OUTPUTS = ("omega_m", "omega_L", "bound", "bound_paper", "psi")

# The plant parameters of a shaft drive that a sweep's sample sets (besides Delta and the gains).
SHAFT_PLANT = ("J_m", "J_L", "b_m", "b_L", "k")
# Those of a belt drive, and of a web line (the belt drive and its span).
BELT_PLANT = ("J_m", "J_L", "b_m", "b_L", "K_b", "R_1", "R_2", "R_g1", "R_g2")
WEB_PLANT = (*BELT_PLANT, "R_w", "L_w", "EA", "v_ref")


# ------------------------------------------------------------------------------------------
# The speed loop of a drive
# ------------------------------------------------------------------------------------------


@dataclass
class Run:
    """Twin drives (b: with Delta, 0: Delta = 0) at the communication points t_0..t_N."""

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
        """|omega_L^b - omega_L^0| at every communication point."""
        return np.abs(self.omega_L_b - self.omega_L_0)


class SpringDamperShaft:
    """The backlash-free twin of a shaft drive with a damper d in the shaft (docs/model.md §3,
    "With a damper"): the linear spring-damper psi = k u + d u', which can pull, stepped exactly
    under a torque held over each step (x_n+1 = e^{M h} x_n with the torque a constant entry of
    the state). The FMU cannot be this twin: its force never pulls, with or without a gap. It
    answers the few calls twin_run makes of an instance."""

    def __init__(self, plant: dict[str, float]):
        j_m, j_l, b_m, b_l, k, d = (plant[n] for n in ("J_m", "J_L", "b_m", "b_L", "k", "d"))
        # x = [theta_m, omega_m, theta_L, omega_L, tau_m]
        m = np.zeros((5, 5))
        m[0, 1] = m[2, 3] = 1.0
        m[1] = [-k / j_m, -(b_m + d) / j_m, k / j_m, d / j_m, 1.0 / j_m]
        m[3] = [k / j_l, d / j_l, -k / j_l, -(b_l + d) / j_l, 0.0]
        self.m = m
        self.x = np.zeros(5)
        self.h: float | None = None
        self.step_matrix = np.eye(5)

    def outputs(self, names: tuple[str, ...]) -> dict[str, float]:
        index = {"omega_m": 1, "omega_L": 3}
        return {n: float(self.x[index[n]]) for n in names if n in index}

    def step(self, t: float, h: float, tau_m: float) -> None:
        if h != self.h:
            self.h, self.step_matrix = h, _expm(self.m * h)
        self.x[4] = tau_m
        self.x = self.step_matrix @ self.x

    def free(self) -> None:
        pass


def _expm(a: np.ndarray) -> np.ndarray:
    """e^a by scaling and squaring of its Taylor series (small matrices of one step)."""
    norm = float(np.max(np.sum(np.abs(a), axis=1)))
    squarings = max(0, math.ceil(math.log2(norm / 0.25))) if norm > 0.25 else 0
    scaled = a / 2.0**squarings
    term = np.eye(a.shape[0])
    total = term.copy()
    for k in range(1, 24):
        term = term @ scaled / k
        total += term
    for _ in range(squarings):
        total = total @ total
    return total


def bound_sup(archive: fmu.Archive, params: dict[str, float]) -> float:
    """`bound_sup` of an instance of `archive` with these parameters."""
    inst = archive.co_simulation(params=params)
    try:
        return inst.get("bound_sup")[0]
    finally:
        inst.free()


def twin_run(
    archive: fmu.Archive,
    plant: dict[str, float],
    delta: float,
    kp: float,
    ki: float,
    ref: Callable[[float], float],
    horizon: float,
    h: float,
) -> Run:
    """The PI loop closed on each of two instances of `archive` (Delta = `delta` and Delta = 0),
    from rest, for `horizon` seconds at the communication step `h`; `plant` holds the drive's
    parameters by their FMU names, `ref` is the motor-speed reference w_ref(t). With a damper in
    the shaft (`d` > 0 in `plant`) the twin is the spring-damper (SpringDamperShaft), which the
    bound is measured against."""
    common = dict(plant, Kp=kp, Ki=ki)
    with_b = archive.co_simulation(params=dict(common, Delta=delta))
    if plant.get("d", 0.0) > 0.0:
        without = SpringDamperShaft(plant)
    else:
        without = archive.co_simulation(params=dict(common, Delta=0.0))
    try:
        n = int(round(horizon / h))
        cols = {k: np.zeros(n + 1) for k in ("ref", "wmb", "wLb", "wm0", "wL0", "taub", "tau0", "b", "bp")}
        contact = np.zeros(n + 1, dtype=int)
        x_b = x_0 = 0.0  # controller integrator states
        for i in range(n + 1):
            t = i * h
            ob, o0 = with_b.outputs(SHAFT_OUTPUTS), without.outputs(SHAFT_OUTPUTS)
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
            with_b.step(t, h, tau_m=tau_b)
            without.step(t, h, tau_m=tau_0)
            x_b += h * e_b
            x_0 += h * e_0
        sup = with_b.get("bound_sup")[0]
    finally:
        with_b.free()
        without.free()
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


def reference_frequency(poles: Iterable[Iterable[float]]) -> float:
    """The reversing reference's frequency [Hz]: the closed-loop poles' mean natural frequency,
    where h oscillates, so that the deviation comes close to the true bound. `poles` as the
    design answer lists them (backlash_fmu.design(...)["poles"]), [re, im] pairs."""
    return float(np.mean([math.hypot(re, im) for re, im in poles])) / (2 * math.pi)


def references(f_ref: float, amplitude: float = SPEED) -> dict[str, Callable[[float], float]]:
    """The motor-speed references by name: "step" (constant `amplitude`) and "sine" (`amplitude`
    sin(2 pi f_ref t), reversing)."""
    return {
        "step": lambda t: amplitude,
        "sine": lambda t: amplitude * math.sin(2.0 * math.pi * f_ref * t),
    }


def trapezoid(amplitude: float, ramp: float, hold: float) -> Callable[[float], float]:
    """The trapezoid reference: from 0 up to `amplitude` in `ramp` seconds, held for `hold`, back to
    0 in `ramp`, then 0."""
    def at(t: float) -> float:
        if t < ramp:
            return amplitude * t / ramp
        if t < ramp + hold:
            return amplitude
        if t < ramp + hold + ramp:
            return amplitude * (ramp + hold + ramp - t) / ramp
        return 0.0
    return at


class SampledPi:
    """The sampled speed PI with the tension PI that trims its reference (docs/model.md §3, §8):
    at each sample, from the measured motor speed and tension,
        e_T = t_ref - T,   e = ref(t) + kp_t e_T + ki_t x_T - omega_m,   tau_m = kp e + ki x_c,
        x_c += h e,   x_T += h e_T      (x_c = x_T = 0 at the start; the tension loop off with
    kp_t = ki_t = 0). The law of the twin web run, and of a system's controller closed here."""

    def __init__(self, kp: float, ki: float, ref: Callable[[float], float], h: float, *,
                 kp_t: float = 0.0, ki_t: float = 0.0, t_ref: float = 0.0):
        self.kp, self.ki, self.ref, self.h = kp, ki, ref, h
        self.kp_t, self.ki_t, self.t_ref = kp_t, ki_t, t_ref
        self.x_c = self.x_t = 0.0

    def torque(self, t: float, omega_m: float, tension: float = 0.0) -> float:
        """The sample at time t: the torque, and the integrators' update."""
        e_t = self.t_ref - tension
        e = self.ref(t) + self.kp_t * e_t + self.ki_t * self.x_t - omega_m
        tau = self.kp * e + self.ki * self.x_c
        self.x_c += self.h * e
        self.x_t += self.h * e_t
        return tau


# ------------------------------------------------------------------------------------------
# The web line: speed loop and tension loop
# ------------------------------------------------------------------------------------------


# What the twin web run reads at every communication point (besides `contact`).
WEB_OUTPUTS = ("omega_m", "omega_L", "T", "bound", "bound_T")
# Speed reference on the motor: amplitude [rad/s] and frequency [Hz] of the reversing sine.
SPEED_AMPLITUDE = 30.0
SPEED_FREQUENCY = 5.0
# Tension PI: Kp_T [rad/s per N], Ki_T [rad/s² per N] (slowest closed-loop poles -4.3 ± 4.0j),
# and the tension set point T_ref [N].
KP_T = 0.01
KI_T = 0.05
T_REF = 2.0
# Upstream web: speed v_in [m/s] and tension T_in [N], held.
V_IN = 0.0
T_IN = 0.0


@dataclass
class WebRun:
    """Twin web lines (b: with Delta, 0: Delta = 0) at the communication points."""

    t: np.ndarray
    T_b: np.ndarray
    T_0: np.ndarray
    omega_L_b: np.ndarray
    omega_L_0: np.ndarray
    bound_T: np.ndarray
    bound: np.ndarray
    contact: np.ndarray
    bound_T_sup: float
    bound_sup: float

    @property
    def dT(self) -> np.ndarray:
        """|T^b - T^0| at every communication point."""
        return np.abs(self.T_b - self.T_0)

    @property
    def d_omega_L(self) -> np.ndarray:
        """|omega_L^b - omega_L^0| at every communication point."""
        return np.abs(self.omega_L_b - self.omega_L_0)

    @property
    def switches(self) -> int:
        """Changes of the contact mode between consecutive communication points."""
        return int(np.count_nonzero(np.diff(self.contact)))


def web_line(archive: fmu.Archive, params: dict[str, float]) -> fmu.CoSimulation:
    """An instance of BacklashWeb's `archive` with `params`, its upstream web (v_in, T_in) held
    at V_IN, T_IN."""
    return archive.co_simulation(params=dict(params, v_in=V_IN, T_in=T_IN))


def bound_t_sup(archive: fmu.Archive, params: dict[str, float]) -> float:
    """`bound_T_sup` of a web line with these parameters."""
    inst = web_line(archive, params)
    try:
        return inst.get("bound_T_sup")[0]
    finally:
        inst.free()


def web_reference(t: float) -> float:
    """The motor-speed reference w_ref0 [rad/s]: a sine that reverses the drive."""
    return SPEED_AMPLITUDE * math.sin(2.0 * math.pi * SPEED_FREQUENCY * t)


def twin_web_run(archive: fmu.Archive, params: dict[str, float], kp: float, ki: float, horizon: float,
                 h: float, *, kp_t: float = KP_T, ki_t: float = KI_T, t_ref: float = T_REF,
                 ref: Callable[[float], float] = web_reference) -> WebRun:
    """The speed and tension PI loops closed on each of two web lines of BacklashWeb's `archive`
    (the Delta of `params` and Delta = 0), from rest and T = 0, for `horizon` seconds at the
    communication step `h`; the tension loop's gains are `kp_t`, `ki_t` (default KP_T, KI_T), its
    set point `t_ref` (T_REF), the motor-speed reference w_ref0 is `ref` (web_reference).

    The sampling, exactly (a twin run written out elsewhere agrees bit for bit when it does the
    same): each line is `web_line(archive, dict(params, Kp=kp, Ki=ki, Kp_T=kp_t, Ki_T=ki_t))`
    (the twin with Delta = 0.0 besides), n = round(horizon / h) steps; at t_i = i * h, i = 0..n,
    both lines' outputs (WEB_OUTPUTS and contact) are read, then, for i < n, on each line with
    its own integrators x_c, x_T (both 0.0 at the start):
        e_T = t_ref - T,   e = ref(t_i) + kp_t * e_T + ki_t * x_T - omega_m
        step(t_i, h, tau_m = kp * e + ki * x_c),   x_c += h * e,   x_T += h * e_T
    (the line with Delta first). bound_T_sup and bound_sup are read from the line with Delta
    after the last step."""
    common = dict(params, Kp=kp, Ki=ki, Kp_T=kp_t, Ki_T=ki_t)
    twins = (web_line(archive, common), web_line(archive, dict(common, Delta=0.0)))
    try:
        n = int(round(horizon / h))
        cols = np.zeros((n + 1, 2, len(WEB_OUTPUTS)))
        contact = np.zeros(n + 1, dtype=int)
        pis = [SampledPi(kp, ki, ref, h, kp_t=kp_t, ki_t=ki_t, t_ref=t_ref) for _ in twins]
        for i in range(n + 1):
            t = i * h
            outs = [inst.outputs(WEB_OUTPUTS) for inst in twins]
            for j, out in enumerate(outs):
                cols[i, j] = [out[name] for name in WEB_OUTPUTS]
            contact[i] = outs[0]["contact"]
            if i == n:
                break
            for inst, out, pi in zip(twins, outs, pis):
                inst.step(t, h, tau_m=pi.torque(t, out["omega_m"], out["T"]))
        t_sup, sup = twins[0].get("bound_T_sup", "bound_sup")
    finally:
        for inst in twins:
            inst.free()
    column = {name: k for k, name in enumerate(WEB_OUTPUTS)}
    return WebRun(
        t=np.arange(n + 1) * h,
        T_b=cols[:, 0, column["T"]],
        T_0=cols[:, 1, column["T"]],
        omega_L_b=cols[:, 0, column["omega_L"]],
        omega_L_0=cols[:, 1, column["omega_L"]],
        bound_T=cols[:, 0, column["bound_T"]],
        bound=cols[:, 0, column["bound"]],
        contact=contact,
        bound_T_sup=t_sup,
        bound_sup=sup,
    )


# ------------------------------------------------------------------------------------------
# One sample of a tolerance sweep
# ------------------------------------------------------------------------------------------


def _ratio(dev: float, sup: float) -> float:
    """dev / sup, with a bound of 0 (no backlash) giving 0 for no deviation and inf for one."""
    return dev / sup if sup > 0 else (0.0 if dev == 0 else math.inf)


def sample_row(archive: fmu.Archive, index: int, params: dict[str, float], settings: dict[str, Any]) -> dict:
    """One sample of a sweep, reduced to what the table records; `archive` is the model's
    (settings["model"]: "shaft", the default, on BacklashShaft; "belt" on BacklashBelt; "web" on
    BacklashWeb). Pure: the same inputs give the same row, bit for bit.

    - shaft, belt: the twin speed loop (`twin_run`) at these parameters (SHAFT_PLANT or
      BELT_PLANT, Delta, Kp, Ki) under the sine reference (settings "amplitude", "frequency"),
      for settings "horizon" at step "h": the row has the parameters, max_dev = max
      |omega_L^b - omega_L^0|, bound_sup, ratio = max_dev / bound_sup and meets = max_dev <=
      settings["accuracy"];
    - web: the twin web line (`twin_web_run`) at these parameters (WEB_PLANT, Delta, Kp, Ki, Kp_T,
      Ki_T) under the speed PI and the tension PI (set point settings "T_ref"), the sine
      reference on the motor speed: the speed figures as above (meets only when
      settings["accuracy"] is not None) and max_dev_T = max |T^b - T^0|, bound_T_sup, ratio_T,
      meets_T = max_dev_T <= settings["tension_accuracy"].

    The sine is `references(frequency, amplitude)["sine"]`, amplitude * sin(2.0 * pi * frequency
    * t_i) at t_i = i * h; the maxima are over the communication points t_0..t_n."""
    model = settings.get("model", "shaft")
    if model == "web":
        return _web_row(archive, index, params, settings)
    if model not in ("shaft", "belt"):
        raise ValueError(f"model = {model!r}: choose shaft, belt or web")
    plant = {name: params[name] for name in (SHAFT_PLANT if model == "shaft" else BELT_PLANT)}
    amplitude, frequency = settings["amplitude"], settings["frequency"]
    run = twin_run(archive, plant, params["Delta"], params["Kp"], params["Ki"],
                   references(frequency, amplitude)["sine"], settings["horizon"], settings["h"])
    max_dev = float(run.deviation.max())
    sup = float(run.bound_sup)
    return {
        "sample": index,
        **params,
        "max_dev": max_dev,
        "bound_sup": sup,
        "ratio": _ratio(max_dev, sup),
        "meets": max_dev <= settings["accuracy"],
    }


def _web_row(archive: fmu.Archive, index: int, params: dict[str, float], settings: dict[str, Any]) -> dict:
    """sample_row of a web line."""
    line = {name: params[name] for name in WEB_PLANT}
    line["Delta"] = params["Delta"]
    run = twin_web_run(archive, line, params["Kp"], params["Ki"], settings["horizon"], settings["h"],
                       kp_t=params["Kp_T"], ki_t=params["Ki_T"], t_ref=settings["T_ref"],
                       ref=references(settings["frequency"], settings["amplitude"])["sine"])
    max_dev, sup = float(run.d_omega_L.max()), float(run.bound_sup)
    max_dev_t, sup_t = float(run.dT.max()), float(run.bound_T_sup)
    row = {"sample": index, **params, "max_dev": max_dev, "bound_sup": sup, "ratio": _ratio(max_dev, sup)}
    if settings.get("accuracy") is not None:
        row["meets"] = max_dev <= settings["accuracy"]
    row.update(max_dev_T=max_dev_t, bound_T_sup=sup_t, ratio_T=_ratio(max_dev_t, sup_t),
               meets_T=max_dev_t <= settings["tension_accuracy"])
    return row


def sample_rows(archive: fmu.Archive, samples: list[tuple[int, dict[str, float]]],
                settings: dict[str, Any]) -> list[dict]:
    """A chunk of samples, (index, parameters) each: their rows, in the order given (each
    `sample_row`)."""
    return [sample_row(archive, index, params, settings) for index, params in samples]


# The archives this process has unpacked, by the SHA-256 of their bytes (archive_from_bytes).
_UNPACKED: dict[str, fmu.Archive] = {}
_UNPACKING = threading.Lock()


def archive_digest(data: bytes) -> str:
    """The name of an archive given as bytes: the SHA-256 of its bytes, in hexadecimal."""
    return hashlib.sha256(data).hexdigest()


def archive_from_bytes(data: bytes) -> fmu.Archive:
    """The archive given as bytes, written and unpacked once per process (keyed by its
    digest); both copies are deleted when the process exits."""
    digest = archive_digest(data)
    with _UNPACKING:
        archive = _UNPACKED.get(digest)
        if archive is None:
            folder = tempfile.mkdtemp(prefix="backlash-sweep-")
            path = Path(folder) / "model.fmu"  # any model's archive: the name is not read
            path.write_bytes(data)
            archive = fmu.Archive(path)
            atexit.register(shutil.rmtree, folder, True)
            atexit.register(archive.remove)
            _UNPACKED[digest] = archive
    return archive


def unpacked(digest: str) -> fmu.Archive | None:
    """The archive this process unpacked from bytes of this digest, if any."""
    with _UNPACKING:
        return _UNPACKED.get(digest)


def prepare(fmu_bytes: bytes) -> None:
    """The one-time work of a process before its first sample: imports, unpacking, and loading
    the model's shared library (one instance made and freed)."""
    archive_from_bytes(fmu_bytes).co_simulation(params={"Delta": 0.0}).free()

"""The loops the tests close around the FMU instances of backlash_fmu.fmu.

- Co-Simulation: `Record` (outputs at the communication points), `run_open_loop` (held torques)
  and `run_pi_loop` (the sampled PI of reference.SampledPI closed outside the FMU).
- Model Exchange: `run_loop`, the continuous-time PI loop closed around any right-hand side with
  scipy's solve_ivp. It only needs an object with `derivatives`, `indicators` and the importer's
  event hooks, so that the same code integrates the FMU (`backlash_fmu.fmu.ModelExchange`) and,
  in the reference's own tests, the equations of docs/model.md §1 written in Python
  (`PythonPlant`) and a gearbox's of §10 (`PythonGearbox`); `outputs_along` reads the FMU's
  outputs along a run.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
from backlash_fmu.fmu import EVENT_INDICATORS, STATES, CoSimulation, ModelExchange
from scipy.integrate import solve_ivp

from reference import FREE, MINUS, PLUS, Plant
from reference_continuous import Hold
from reference_two_stage import Gearbox

# ---- Co-Simulation ---------------------------------------------------------------------------

RECORDED = (*STATES, "psi", "bound", "bound_paper")


class Record:
    """Outputs at the communication points t_0..t_N, one row per point."""

    def __init__(self):
        self.rows: list[list[float]] = []
        self.contact: list[int] = []

    def add(self, inst: CoSimulation):
        self.rows.append(inst.get(*RECORDED))
        self.contact.append(inst.contact())

    def arrays(self) -> dict[str, np.ndarray]:
        a = np.array(self.rows)
        out = {n: a[:, j] for j, n in enumerate(RECORDED)}
        out["z"] = a[:, :4]
        out["contact"] = np.array(self.contact)
        return out


def run_open_loop(inst: CoSimulation, tau_m, tau_L, h: float) -> dict[str, np.ndarray]:
    """Held torques, one per step; outputs at every communication point."""
    rec = Record()
    rec.add(inst)
    for k, (tm, tl) in enumerate(zip(tau_m, tau_L)):
        inst.step(inst.t0 + k * h, h, tau_m=float(tm), tau_L=float(tl))
        rec.add(inst)
    return rec.arrays()


def run_pi_loop(inst: CoSimulation, controller, h: float, n: int, w_ref, tau_L) -> dict[str, np.ndarray]:
    """The PI speed loop closed outside the FMU: tau_m from the measured omega_m at each t_k."""
    rec = Record()
    rec.add(inst)
    taus = []
    for k in range(n):
        t = k * h  # time since the start, as in the reference loop
        tau = controller(w_ref(t), inst.get("omega_m")[0])
        taus.append(tau)
        inst.step(inst.t0 + t, h, tau_m=tau, tau_L=tau_L(t))
        rec.add(inst)
    out = rec.arrays()
    out["tau_m"] = np.array(taus)
    return out


# ---- Model Exchange --------------------------------------------------------------------------

DERIVATIVES = tuple(f"der({name})" for name in STATES)
# The drive train's states; BacklashWeb has its span's tension T as a fifth, which the drive-train
# tests hold at 0 (its web decoupled, rigs.WEB_DECOUPLED).
NX, NZ = len(STATES), EVENT_INDICATORS


def state_with_u(plant: Plant, u: float, theta_m=0.2, omega_m=0.5, omega_L=-0.4) -> np.ndarray:
    """[theta_m, omega_m, theta_L, omega_L] with transmission coordinate u (docs/model.md §1)."""
    return np.array([theta_m, omega_m, (plant.r_m * theta_m - u) / plant.r_L, omega_L])


class EquationsOnly:
    """The importer's event hooks of a Python double that has no discrete state: nothing to set,
    no step or event iteration asks for anything."""

    def set_state(self, t, x):
        pass

    def completed_step(self):
        return False, False

    def event_iteration(self):
        return (False, False, False, False, False, 0.0)


class PythonPlant(EquationsOnly):
    """The right-hand side and event indicators of docs/model.md §1 written directly in
    Python, with the same interface as backlash_fmu.fmu.ModelExchange: the double that tests
    run_loop itself."""

    def __init__(self, plant: Plant):
        self.p = plant

    def derivatives(self, t, x, tau_m, tau_L):
        p = self.p
        psi = p.K * p.dead_zone(p.r_m * x[0] - p.r_L * x[2])
        return np.array(
            [x[1], (tau_m - p.b_m * x[1] - p.r_m * psi) / p.J_m, x[3], (tau_L - p.b_L * x[3] + p.r_L * psi) / p.J_L]
        )

    def indicators(self, t, x):
        """The FMU's ten event indicators (docs/model.md §6, §12) of this plant without a damper and
        without friction: u - g, u + g, and the damper's and friction's eight surfaces, which it
        does not have, at 1."""
        u = self.p.r_m * x[0] - self.p.r_L * x[2]
        return np.array([u - self.p.g, u + self.p.g, *[1.0] * (NZ - 2)])


class PythonGearbox(EquationsOnly):
    """The gearbox's field and event indicators of docs/model.md §10 written in Python
    (reference_two_stage.Gearbox) with the interface of a Model Exchange instance over its six
    states: the double that tests run_loop on a gearbox."""

    def __init__(self, box: Gearbox):
        self.box, self.nx, self.nz = box, 6, 18

    def derivatives(self, t, x, tau_m, tau_L):
        return self.box.field(np.asarray(x[:6], dtype=float), tau_m, tau_L)

    def indicators(self, t, x):
        return self.box.indicators(x[:6])


@dataclass
class LoopRun:
    """States at the output times (z: the model's four, xi: the PI integral), the motor torque
    there, and every located crossing of an event indicator as (time, mode before, mode after)."""

    t: np.ndarray
    z: np.ndarray
    xi: np.ndarray
    tau_m: np.ndarray
    switches: list = field(default_factory=list)
    event_infos: list = field(default_factory=list)
    step_answers: list = field(default_factory=list)


def _mode(sides, mesh: int = 0) -> int:
    """A mesh's contact mode from the signs of its indicators [u - g, u + g]: the first two of
    each mesh's six (docs/model.md §6; a gearbox's, §10)."""
    if sides[6 * mesh] > 0:
        return PLUS
    if sides[6 * mesh + 1] < 0:
        return MINUS
    return FREE


def modes(sides, meshes: int = 2) -> tuple[int, ...]:
    """Each mesh's contact mode from the signs of a gearbox's indicators."""
    return tuple(_mode(sides, j) for j in range(meshes))


def run_loop(model, Kp, Ki, holds: list[Hold], t_out, z0, xi0=0.0, rtol=1e-12, atol=1e-15, events=True,
             meshes: int = 1) -> LoopRun:
    """The continuous-time PI of docs/model.md §3 closed around `model`:

        y = [z, xi],   xi' = w_ref - omega_m,
        tau_m = tau_ff + Kp (w_ref - omega_m) + Ki xi,

    integrated by solve_ivp (DOP853) from hold to hold (the signals jump there, so every hold
    starts a new integration), with the model's two event indicators as terminal events: each
    crossing stops the integration at the located root, the importer's event iteration runs
    there, and the integration restarts from the event state. After a crossing an indicator
    is watched only for the crossing back (its event direction is the opposite), so that the
    restart, which lies on the root to round-off, cannot fire the same event again.
    events=False integrates without events (for Delta = 0, where the right-hand side is linear
    and both indicators are u: there is nothing to locate). solve_ivp looks for sign changes at
    its step ends only, so a contact entered and left within one step would go unseen; the
    tests compare the whole switch sequence with the exact one, which would show it.

    z is the drive train's states ([theta_m, omega_m, theta_L, omega_L]; a gearbox's six, with
    `meshes` = 2) and the model has NZ indicators or says how many (`model.nz`). A switch is
    (time, mode before, mode after); a gearbox's (time, mesh, mode before, mode after), one per
    mesh whose mode changed."""
    t_out = np.asarray(t_out, dtype=float)
    t_end, nx, nz = float(t_out[-1]), len(z0), getattr(model, "nz", NZ)
    y = np.array([*z0, xi0], dtype=float)
    t = holds[0].t
    Y_out = np.full((len(t_out), nx + 1), np.nan)
    run = LoopRun(t_out, None, None, None)
    sides = np.sign(model.indicators(t, y)) if events else np.zeros(nz)
    if events and np.any(sides == 0.0):
        raise ValueError("the run must not start on a switching surface")

    for k, hold in enumerate(holds):
        seg_end = min(holds[k + 1].t if k + 1 < len(holds) else math.inf, t_end)

        def rhs(s, yy, hold=hold):
            e = hold.w_ref - yy[1]
            tau = hold.tau_m + Kp * e + Ki * yy[nx]
            return np.append(model.derivatives(s, yy, tau, hold.tau_L), e)

        while t < seg_end:
            functions = []
            if events:
                cache: dict = {}

                def indicator(s, yy, i, cache=cache):
                    key = (s, yy.tobytes())
                    if key not in cache:
                        cache.clear()
                        cache[key] = model.indicators(s, yy)
                    return cache[key][i]

                for i in range(nz):
                    fn = lambda s, yy, i=i: indicator(s, yy, i)  # noqa: E731
                    fn.terminal, fn.direction = True, -sides[i]
                    functions.append(fn)
            sol = solve_ivp(
                rhs, (t, seg_end), y, method="DOP853", rtol=rtol, atol=atol, events=functions or None, dense_output=True
            )
            if sol.status == -1:
                raise RuntimeError(f"solve_ivp failed at t = {t}: {sol.message}")
            stop = float(sol.t[-1])
            mask = (t_out >= t) & (t_out <= stop)
            if np.any(mask):
                Y_out[mask] = sol.sol(t_out[mask]).T
            if sol.status == 1:
                fired = [i for i in range(nz) if len(sol.t_events[i])]
                stop = min(float(sol.t_events[i][0]) for i in fired)
                fired = [i for i in fired if float(sol.t_events[i][0]) == stop]
                y = sol.y_events[fired[0]][0].copy()
                before = modes(sides, meshes)
                for i in fired:
                    sides[i] = -sides[i]
                after = modes(sides, meshes)
                if meshes == 1:
                    run.switches.append((stop, before[0], after[0]))
                else:
                    run.switches += [(stop, j, before[j], after[j]) for j in range(meshes) if before[j] != after[j]]
                model.set_state(stop, y)
                run.event_infos.append(model.event_iteration())
            else:
                y = sol.y[:, -1].copy()
            if stop <= t:
                raise RuntimeError(f"events do not advance at t = {t}")
            t = stop
            model.set_state(t, y)
            run.step_answers.append(model.completed_step())
        if t >= t_end:
            break
    if np.any(np.isnan(Y_out)):
        raise ValueError("output times beyond the last hold's reach")
    starts = np.array([h.t for h in holds])
    idx = np.searchsorted(starts, t_out, side="right") - 1
    run.tau_m = np.array(
        [holds[i].tau_m + Kp * (holds[i].w_ref - w) + Ki * x for i, w, x in zip(idx, Y_out[:, 1], Y_out[:, nx])]
    )
    run.z, run.xi = Y_out[:, :nx], Y_out[:, nx]
    return run


def outputs_along(inst: ModelExchange, run: LoopRun, names=("psi", "bound", "bound_paper")) -> dict[str, np.ndarray]:
    """The FMU's outputs at the run's output times, each read after fmi2SetTime and
    fmi2SetContinuousStates (in Continuous-Time Mode): Real outputs and `contact`. `inst` must
    be one that has not integrated past the first output time: time cannot go back over a
    completed integrator step or an event (FMI 2.0.4 §3.2.2), so a fresh instance reads them."""
    rows, contact = [], []
    for t, z in zip(run.t, run.z):
        inst.set_state(t, z)
        rows.append(inst.get(*names))
        contact.append(inst.contact())
    a = np.array(rows)
    out = {n: a[:, j] for j, n in enumerate(names)}
    out["contact"] = np.array(contact)
    return out

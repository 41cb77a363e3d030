"""A damper in the compliant member (docs/model.md §1 "Damping in the compliant member", §2, §3)
through the FMUs, against the independent reference of damped_reference.py (an exact
piecewise-affine solution by scipy's expm with a proved crossing search, itself checked against
an event-located DOP853 solver in test_damped_reference.py).

- Open loops (BacklashShaft and BacklashBelt, both laws, reversing torques; contact lost at
  u = +-g and by the force reaching 0): the states at every communication point agree with the
  reference to 1e-9 of each quantity's amplitude over the run, and through FMI 3.0's early return
  every switch of the reference is located, one for one, to 1e-9 s.
- The bound: twin runs under the same sampled PI, the backlash FMU against the linear
  spring-damper (which can pull) computed here exactly by expm, never exceed the FMU's `bound`,
  which the rule without a damper (K g int|h|) would not cover.
"""

from __future__ import annotations

import numpy as np
import pytest
from scipy.linalg import expm

import archives
import damped_reference as ref
from loops import run_open_loop, run_pi_loop
from reference import SampledPI
from rigs import RIGS

H = 0.01
T_END = 2.4
STEPS = round(T_END / H)


def fmu_params(model: str, zeta: float, law: int, Delta: float | None = None) -> tuple[dict, dict]:
    """The FMU's parameters (the model's test rig with a damper of contact damping ratio zeta)
    and the same plant for the reference."""
    params = dict(RIGS[model][0])
    if Delta is not None:
        params["Delta"] = Delta
    if model == "BacklashShaft":
        p = ref.shaft_params(zeta, Delta=params["Delta"])
        params["d"] = p["D"]
    else:
        p = ref.belt_params(zeta, Delta=params["Delta"])
        params["D_b"] = p["D"]
    params["contact_law"] = law
    return params, p


def square_torque(amplitude: float = 4.0, half_period: float = 0.3) -> np.ndarray:
    """+-amplitude, reversing every half_period, held over each step of H."""
    t = np.arange(STEPS) * H
    return np.where(np.floor(t / half_period + 1e-9) % 2 == 0, amplitude, -amplitude)


CASES = [
    (model, zeta, law)
    for model in ("BacklashShaft", "BacklashBelt")
    for zeta in (0.05, 0.5)
    for law in (1, 2)
]


@pytest.mark.parametrize("model, zeta, law", CASES)
def test_open_loop_agrees_with_the_reference(model, zeta, law):
    params, p = fmu_params(model, zeta, law)
    tau = square_torque()
    t = np.arange(STEPS + 1) * H
    expected = ref.simulate(p, law, (0, 0, 0, 0), t, tau, 0.0, t)
    inst = archives.shared(model, 2).co_simulation(params=params)
    try:
        got = run_open_loop(inst, tau, np.zeros(STEPS), H)
    finally:
        inst.free()
    for j, name in enumerate(("theta_m", "omega_m", "theta_L", "omega_L")):
        scale = np.max(np.abs(expected.z[:, j]))
        err = np.max(np.abs(got[name] - expected.z[:, j])) / scale
        assert err <= 1e-9, f"{model} zeta {zeta} law {law}: {name} off by {err:.1e} of its amplitude"
    psi_scale = np.max(np.abs(expected.psi))
    assert np.max(np.abs(got["psi"] - expected.psi)) <= 1e-9 * psi_scale
    assert np.array_equal(got["contact"], expected.contact)
    # The run crosses the surfaces it is meant to: contact lost by the force reaching 0 with u
    # still past the flank, and (law 1) the cap.
    kinds = {s.surfaces for s in expected.switches}
    assert any(any(x.startswith("zero") for x in k) for k in kinds), kinds
    assert any(any(x.startswith("flank") for x in k) for k in kinds), kinds
    if law == 1:
        assert any(any(x.startswith("equal") for x in k) for k in kinds), kinds


@pytest.mark.parametrize("model, zeta, law", [c for c in CASES if c[1] == 0.5])
def test_every_switch_is_located(model, zeta, law):
    """FMI 3.0 Co-Simulation returns early at each contact switch (docs/model.md §7): the
    early-return instants are the reference's switches, one for one, to 1e-9 s."""
    params, p = fmu_params(model, zeta, law)
    h = 0.05
    n = round(T_END / h)
    tau = np.where(np.floor(np.arange(n) * h / 0.3 + 1e-9) % 2 == 0, 4.0, -4.0)
    t = np.arange(n + 1) * h
    expected = ref.simulate(p, law, (0, 0, 0, 0), t, tau, 0.0, t)
    inst = archives.shared(model, 3).co_simulation(params=params, early_return=True, event_mode=True)
    stops = []
    try:
        for k in range(n):
            t, t_end = k * h, (k + 1) * h
            inst.set_inputs(tau_m=float(tau[k]), tau_L=0.0)
            while True:
                event, terminate, early, last = inst.do_step(t, t_end - t)
                assert not terminate
                if not early:
                    break
                stops.append(last)
                inst.fmu.enterEventMode()
                inst.fmu.updateDiscreteStates()
                inst.fmu.enterStepMode()
                t = last
    finally:
        inst.free()
    times = np.array([s.time for s in expected.switches])
    assert len(stops) == len(times), f"{len(stops)} early returns, {len(times)} switches"
    assert np.max(np.abs(np.array(stops) - times)) <= 1e-9


def linear_twin_sampled(p: dict, gains, h: float, n: int, w_ref) -> np.ndarray:
    """omega_L of the linear spring-damper twin (psi = K u + D u') under reference.SampledPI,
    exactly: x_k+1 = e^{A h} x_k + (int_0^h e^{A s} ds) B tau_k, by expm of the augmented matrix."""
    J_m, J_L, b_m, b_L, r_m, r_L, K, D = (p[k] for k in ("J_m", "J_L", "b_m", "b_L", "r_m", "r_L", "K", "D"))
    psi = np.array([K * r_m, D * r_m, -K * r_L, -D * r_L])
    A = np.zeros((5, 5))
    A[0, 1] = 1.0
    A[1, :4] = -r_m * psi / J_m
    A[1, 1] -= b_m / J_m
    A[1, 4] = 1.0 / J_m
    A[2, 3] = 1.0
    A[3, :4] = r_L * psi / J_L
    A[3, 3] -= b_L / J_L
    step = expm(A * h)
    pi = SampledPI(*gains, h)
    x = np.zeros(5)
    out = [0.0]
    for k in range(n):
        x[4] = pi(w_ref(k * h), x[1])
        x = step @ x
        out.append(x[3])
    return np.array(out)


@pytest.mark.parametrize("law", [1, 2])
@pytest.mark.parametrize("model, Delta", [("BacklashShaft", None), ("BacklashShaft", 0.0), ("BacklashBelt", None)])
def test_twin_difference_never_exceeds_the_damped_bound(model, Delta, law):
    """The loop sampled at 1e-3 s (as test_bound.py does for the plant without a damper), a
    reversing speed reference; the FMU's `bound` follows its own trajectory (docs/model.md §3)."""
    params, p = fmu_params(model, 0.5, law, Delta)
    gains = tuple(RIGS[model][1][g] for g in ("Kp", "Ki"))
    params.update(Kp=gains[0], Ki=gains[1])
    h, n = 1e-3, 3000

    def w_ref(t):
        return 1.5 * np.sin(2 * np.pi * t + 0.3)

    inst = archives.shared(model, 2).co_simulation(params=params)
    try:
        b = run_pi_loop(inst, SampledPI(*gains, h), h, n, w_ref, lambda t: 0.0)
        bound_sup = inst.get("bound_sup")[0]
    finally:
        inst.free()
    w0 = linear_twin_sampled(p, gains, h, n, w_ref)
    dev = np.abs(b["omega_L"] - w0)
    assert np.max(dev) > 1e-3, "the backlash must make a visible difference"
    assert np.all(dev <= b["bound"] + 1e-12), f"max deviation / bound = {np.max(dev[1:] / b['bound'][1:])}"
    # The rule without a damper, K g int_0^t |h| <= K g int_0^inf |h| = bound_sup, is exceeded:
    # the damper's term of the bound is what covers the deviation.
    assert np.max(dev) > bound_sup, (np.max(dev), bound_sup)


# Off every switching surface at the start (the solver's events need a definite side): the motor
# turned by 1e-4 rad, inside the gaps of the rigs and on the flank without one.
Z0 = (1e-4, 0.0, 0.0, 0.0)


class BoundReader:
    """An ME instance for loops.run_loop that also reads `bound` at each completed integrator
    step, in the instance that integrates (the damped bound's terms are gathered at the
    importer's events and completed steps: a fresh instance would not have them)."""

    def __init__(self, inst):
        self.inst = inst
        self.time = 0.0
        self.read: dict[float, float] = {}

    def derivatives(self, t, x, tau_m, tau_L):
        return self.inst.derivatives(t, x, tau_m, tau_L)

    def indicators(self, t, x):
        return self.inst.indicators(t, x)

    def set_state(self, t, x):
        self.time = t
        self.inst.set_state(t, x)

    def event_iteration(self):
        return self.inst.event_iteration()

    def completed_step(self):
        answer = self.inst.completed_step()
        self.read[self.time] = self.inst.get("bound")[0]
        return answer


@pytest.mark.parametrize("law", [1, 2])
@pytest.mark.parametrize("model, Delta", [("BacklashShaft", None), ("BacklashShaft", 0.0), ("BacklashBelt", None)])
def test_model_exchange_twin_difference_never_exceeds_the_damped_bound(model, Delta, law):
    """The continuous PI loop closed around the ME instance by loops.run_loop (events located on
    the six indicators, docs/model.md §6), against the exact linear twin of the reference; the
    bound is the ME form of docs/model.md §3, read at every hold."""
    from loops import run_loop
    from reference_continuous import Hold

    params, p = fmu_params(model, 0.5, law, Delta)
    gains = tuple(RIGS[model][1][g] for g in ("Kp", "Ki"))
    params.update(Kp=gains[0], Ki=gains[1])
    bp = np.arange(0.0, 2.0 + 1e-9, 0.05)
    w = 1.5 * np.sin(2 * np.pi * bp[:-1] + 0.3)
    holds = [Hold(t=float(t), w_ref=float(x)) for t, x in zip(bp[:-1], w)]
    inst = archives.shared(model, 2).model_exchange(params=params)
    reader = BoundReader(inst)
    try:
        run = run_loop(reader, *gains, holds, bp, Z0)
    finally:
        inst.free()
    twin = ref.linear_twin_pi(p, Z0, bp, w, 0.0, gains, bp)
    dev = np.abs(run.z[:, 3] - twin.z[:, 3])
    bound = np.array([reader.read[float(t)] for t in bp[1:]])
    assert np.max(dev) > 1e-3
    # The ME trajectory is the importer's (rtol 1e-12), the twin exact: 1e-9 covers the difference.
    assert np.all(dev[1:] <= bound + 1e-9), f"max deviation / bound = {np.max(dev[1:] / bound)}"


@pytest.mark.parametrize("law", [1, 2])
def test_the_design_answers_for_the_damped_loop(law):
    """backlash_fmu.design with a damper: the gains and bound_sup are those of the loop with the
    spring-damper (docs/model.md §3): bound_sup per unit Delta equals K int_0^inf |h| of that loop,
    computed here by expm on a 1e-4 s grid to 30 s (trapezoid; the loop has decayed by 1e-9
    there, and the grid's error is second order: 1e-6 relative allowed); and it differs from the
    answer without a damper."""
    import backlash_fmu

    p = ref.shaft_params(0.5)
    answer = backlash_fmu.design("shaft", accuracy=0.02, d=p["D"], contact_law=law)
    plain = backlash_fmu.design("shaft", accuracy=0.02)
    assert answer["plant"]["d"] == p["D"] and answer["plant"]["contact_law"] == law
    gains = (answer["Kp"], answer["Ki"])
    A, D_1 = ref.twin_loop(p, gains)
    dt = 1e-4
    step = expm(A * dt)
    v, h = D_1.copy(), []
    for _ in range(int(30.0 / dt) + 1):
        h.append(v[3])
        v = step @ v
    h = np.abs(np.array(h))
    l1 = float(np.sum(0.5 * (h[1:] + h[:-1])) * dt)
    expected = p["K"] * l1
    assert abs(answer["bound_sup_per_unit_delta"] / expected - 1) <= 1e-6
    assert abs(answer["bound_sup_per_unit_delta"] / plain["bound_sup_per_unit_delta"] - 1) > 0.1



@pytest.mark.parametrize("law", [1, 2])
def test_bound_rate_with_a_damper(law):
    """The output derivative of `bound` (fmi2GetRealOutputDerivatives) with a damper is K g |h| +
    D max|h| |u'| while V grows (docs/model.md §3): against the growth of `bound` itself over a
    short step, where max|h| does not move (one piece). The open-loop shaft with a reversing
    torque, read at every step of 1e-4 s; the central difference of bound between t - h and
    t + h has an error of O(h^2) of its second derivative, here 1e-4 of the rate (measured 3e-6)."""
    params, _ = fmu_params("BacklashShaft", 0.5, law)
    inst = archives.shared("BacklashShaft", 2).co_simulation(params=params)
    h, n = 1e-4, 12000
    vr = inst.refs(["bound"])
    values, rates = [], []
    try:
        for k in range(n):
            t = k * h
            values.append(inst.get("bound")[0])
            rates.append(inst.fmu.getRealOutputDerivatives(vr, [1])[0])
            inst.step(t, h, tau_m=4.0 if (t // 0.3) % 2 == 0 else -4.0, tau_L=0.0)
    finally:
        inst.free()
    values, rates = np.array(values), np.array(rates)
    central = (values[2:] - values[:-2]) / (2 * h)
    inner = rates[1:-1]
    # Where max|h| steps up (a new piece), the difference jumps: those samples are left out, as
    # are the switching instants, where |u'| counts on one side only.
    smooth = np.abs(np.diff(central, 2, prepend=central[0], append=central[-1])) < 1e-3 * np.max(np.abs(central))
    assert np.count_nonzero(smooth) > 0.9 * smooth.size
    err = np.abs(inner[smooth] - central[smooth]) / np.max(np.abs(central))
    assert np.max(err) <= 1e-4, np.max(err)

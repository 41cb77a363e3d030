"""Bearing friction with stiction in the FMUs (docs/model.md §12), Co-Simulation, FMI 2.0 and 3.0,
through fmpy, against the independent reference reference_friction.py.

Tolerances:
- states and psi: 1e-9 relative per signal (max abs error / max abs value, as test_open_loop.py).
  The reference agrees with itself at rtol 1e-12 and 1e-13 and with Radau to 1e-11 on the same
  runs (test_reference_friction.py), so 1e-9 leaves a margin of 100 over its error; a stop or a
  breakaway stepped over instead of located is off by far more (the speed a body keeps or lacks
  over a fraction of a step, ~1e-3 of these signals).
- contact, sliding_m, sliding_L: equal at every communication point farther than EVENT_MARGIN
  from a switch of the reference (closer, the two computations may put the switch on either side
  of the point).
- without friction (tau_c = 0, whatever the peaks): the same bits as a run that never sets the
  friction parameters (§12: "With every tau_c = 0 everything is as before, bit for bit").

Each test is skipped, with the reason, while the archive has no variable `tau_c_m`; it runs as
soon as the archive has it.
"""

from __future__ import annotations

import numpy as np
import pytest

import archives
import scenarios
from loops import RECORDED
from rigs import RIGS
from signals import rel_err, reversing_torques

TOL = 1e-9
EVENT_MARGIN = 1e-9  # s
MODELS = ("BacklashShaft", "BacklashBelt")
INTEGERS = ("contact", "sliding_m", "sliding_L")
STATES_AND_PSI = ("theta_m", "omega_m", "theta_L", "omega_L", "psi")


def _archive_with_friction(model: str, fmi: int):
    archive = archives.require(model, fmi)
    if "tau_c_m" not in archive.variables:
        pytest.skip(f"{archive.path.name} (FMI {fmi}) has no variable tau_c_m: its FMUs do not expose "
                    "bearing friction (docs/model.md §12) yet")
    return archive


def _integers(inst, names):
    get = inst.fmu.getInteger if inst.fmi == 2 else inst.fmu.getInt32
    return list(get(inst.refs(names)))


def _run(archive, name: str, params: dict, tau_m, tau_L, h: float, reals=RECORDED) -> dict[str, np.ndarray]:
    """Held torques through a Co-Simulation instance; `reals` and the Integer outputs at every
    communication point t_0..t_N."""
    inst = archive.co_simulation(name, params)
    rows, ints = [], []
    try:
        rows.append(inst.get(*reals))
        ints.append(_integers(inst, INTEGERS))
        for k, (tm, tl) in enumerate(zip(tau_m, tau_L)):
            inst.step(k * h, h, tau_m=float(tm), tau_L=float(tl))
            rows.append(inst.get(*reals))
            ints.append(_integers(inst, INTEGERS))
    finally:
        inst.free()
    rows, ints = np.array(rows), np.array(ints)
    out = {n: rows[:, j] for j, n in enumerate(reals)}
    out.update({n: ints[:, j] for j, n in enumerate(INTEGERS)})
    return out


@pytest.mark.parametrize("fmi", [2, 3])
@pytest.mark.parametrize("model", MODELS)
def test_slow_reversal_matches_the_reference(model, fmi):
    """Friction on both bodies, a slow reversing motor torque (scenarios.FRICTION): the load sticks
    while the motor crosses the gap at each reversal, then breaks away; states, psi and the modes
    as reference_friction.py computes them."""
    archive = _archive_with_friction(model, fmi)
    params, _ = RIGS[model]
    tau_m, tau_L = scenarios.friction_torques()
    h = scenarios.FRICTION_STEP
    out = _run(archive, f"friction-{model}-{fmi}", {**params, **scenarios.FRICTION}, tau_m, tau_L, h,
               reals=STATES_AND_PSI)
    ref, sim = scenarios.friction_reversal_reference(model)
    errors = {name: rel_err(out[name], ref[name]) for name in STATES_AND_PSI}
    assert max(errors.values()) <= TOL, f"{model} FMI {fmi}: {errors} ({len(sim.events)} switches)"

    t = ref["time"]
    times = np.array(sim.event_times)
    near = np.array([np.any(np.abs(times - tk) <= EVENT_MARGIN) for tk in t])
    assert np.count_nonzero(near) <= 0.05 * len(t), "too few communication points away from switches"
    for name in INTEGERS:
        wrong = np.nonzero((out[name] != ref[name]) & ~near)[0]
        assert wrong.size == 0, f"{model} FMI {fmi}: {name} differs at t = {t[wrong][:5]} (FMU {out[name][wrong][:5]}, " \
                                f"reference {ref[name][wrong][:5]})"
    # docs/model.md §12: a body that stops inside a step is set at rest exactly.
    for body in ("m", "L"):
        stuck = out[f"sliding_{body}"] == 0
        assert np.count_nonzero(stuck) > 0 and np.all(out[f"omega_{body}"][stuck] == 0.0)


@pytest.mark.parametrize("fmi", [2, 3])
@pytest.mark.parametrize("model", MODELS)
def test_zero_friction_is_bit_identical_to_the_model_without_it(model, fmi):
    """tau_c_m = tau_c_L = 0 (peaks set, which then mean nothing): every output, bound included,
    is the same bits as a run that never sets the friction parameters, on a run that crosses the
    gap again and again; sliding_* is the sign of the body's speed in both."""
    archive = _archive_with_friction(model, fmi)
    params, gains = RIGS[model]
    h, n = 0.02, 200
    tau_m, tau_L = reversing_torques(n, h, 1.5, 0.6)
    plain = _run(archive, f"plain-{model}-{fmi}", {**params, **gains}, tau_m, tau_L, h)
    zero = {"tau_c_m": 0.0, "tau_c_L": 0.0, "peak_m": 1.5, "peak_L": 2.0}
    frictionless = _run(archive, f"zero-{model}-{fmi}", {**params, **gains, **zero}, tau_m, tau_L, h)
    assert len(set(plain["contact"])) == 3, "the run must cross the gap both ways"
    for name in (*RECORDED, *INTEGERS):
        assert np.array_equal(plain[name], frictionless[name]), f"{model} FMI {fmi}: {name} differs"
    for run in (plain, frictionless):
        assert np.array_equal(run["sliding_m"], np.sign(run["omega_m"]))
        assert np.array_equal(run["sliding_L"], np.sign(run["omega_L"]))

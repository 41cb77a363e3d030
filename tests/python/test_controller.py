"""BacklashController through fmpy (docs/model.md §9): its archives pass fmpy's validation, it
serves Co-Simulation only and says so, and its torque follows the PI law written in Python
(twin.SampledPi) to the bit, one sample late, through both standards. The systems it closes are
run in the masters by test_masters.py."""

from __future__ import annotations

import zipfile

import pytest
from backlash_fmu import twin
from backlash_fmu.fmu import Archive, fmu_path
from fmpy.validation import validate_fmu

CONTROLLER = "BacklashController"


@pytest.mark.parametrize("fmi", [2, 3])
def test_fmpy_validation_finds_no_problem(fmi):
    assert validate_fmu(str(fmu_path(CONTROLLER, fmi))) == []


@pytest.mark.parametrize("fmi", [2, 3])
def test_the_archive_is_co_simulation_only_with_its_documentation(fmi):
    path = fmu_path(CONTROLLER, fmi)
    with Archive(path) as archive:
        assert archive.md.modelExchange is None and archive.md.coSimulation is not None
        assert archive.md.coSimulation.canHandleVariableCommunicationStepSize is False
    with zipfile.ZipFile(path) as z:
        page = z.read("documentation/index.html").decode()
    assert "u_k = Kp e + Ki x_c" in page and "<td>tau_m</td>" in page.replace("<code>", "").replace("</code>", "")


@pytest.mark.parametrize("fmi", [2, 3])
def test_the_torque_is_the_python_law_one_sample_late(fmi):
    """A measured speed and tension that change every step; the controller's torque after step k
    is the Python law's sample k, to the bit (the same operations in the same order)."""
    h, kp, ki = 1e-3, 42.7, 179.2
    params = {"Kp": kp, "Ki": ki, "Kp_T": 0.01, "Ki_T": 0.05, "T_ref": 2.0, "h": h,
              "reference": 3, "amplitude": 0.05, "frequency": 1.41}
    law = twin.SampledPi(kp, ki, twin.references(1.41, 0.05)["sine"], h, kp_t=0.01, ki_t=0.05, t_ref=2.0)
    with Archive(fmu_path(CONTROLLER, fmi)) as archive:
        inst = archive.co_simulation("pi", params)
        try:
            assert inst.get("tau_m") == [0.0]
            t = 0.0
            for k in range(500):
                omega, tension = 0.03 * (k % 17) - 0.2, 1.5 + 0.01 * (k % 5)
                inst.step(t, h, omega_m=omega, T=tension)
                t += h
                assert inst.get("tau_m") == [law.torque(k * h, omega, tension)], k
        finally:
            inst.free()


def test_what_it_does_not_offer_is_refused_with_the_reason():
    with Archive(fmu_path(CONTROLLER, 2)) as archive:
        with pytest.raises(Exception):
            archive.model_exchange("me")
        # Each refusal is fmi2Error: the instance is in Error afterwards, so one instance each.
        for call, reason in ((lambda i: i.fmu.getFMUstate(), "canGetAndSetFMUstate = false"),
                             (lambda i: i.fmu.doStep(0.0, 2e-3), "is not the sample period h = 0.001")):
            inst = archive.co_simulation("cs", {"h": 1e-3})
            try:
                assert inst.refused(lambda: call(inst), reason)
            finally:
                inst.free()
    with Archive(fmu_path(CONTROLLER, 3)) as archive:
        with pytest.raises(Exception):
            archive.co_simulation("events", event_mode=True)

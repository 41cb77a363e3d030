"""Every output of every FMU in a directory over scenarios with contact switches, as SHA-256
digests: one per model and one of them all.

A change that must keep behaviour (a refactor) keeps these digests: run it on the archives built
before and after and compare.

    .venv/bin/python scripts/outputs_fingerprint.py target/fmu [--dump FILE]

The models are the FMI 2.0 archives found in the directory (a new model is covered without an
edit here). For each: an open loop with a reversing torque, input ramps set by
fmi2SetRealInputDerivatives, a sampled PI loop closed here, and a start from a non-zero load
speed, at the time scale of its drive's form (a shaft's or a belt's stiffness, read from its
description; a web line's span inputs stay at their start values). After every step it records
every Real variable, `contact` and the output derivatives of the Real outputs, as exact
hexadecimal floats (`--dump` writes them, one line per step).
"""

from __future__ import annotations

import argparse
import hashlib
import math
import shutil
import sys
from pathlib import Path

from fmpy import extract, read_model_description
from fmpy.fmi2 import FMU2Slave

SCENARIOS = ("open", "ramp", "closed", "initial_speed")
STEPS = 1500
DERIVED = ["omega_m", "omega_L", "theta_m", "theta_L", "psi", "bound", "bound_paper"]


def run(path: str, model: str, scenario: str) -> list[str]:
    md = read_model_description(path)
    unzipdir = extract(path)
    fmu = FMU2Slave(guid=md.guid, unzipDirectory=unzipdir, modelIdentifier=model, instanceName="fingerprint")
    lines = [f"# {model} {scenario}"]
    try:
        fmu.instantiate()
        vr = {v.name: v.valueReference for v in md.modelVariables}
        reals = [v.valueReference for v in md.modelVariables if v.type == "Real"]
        derived = [vr[n] for n in DERIVED]
        # The rig's time scale follows the compliant member: a shaft's k, or a belt's K_b.
        shaft = "k" in vr
        gains = {"Kp": 5.0, "Ki": 10.0} if shaft else {"Kp": 0.05, "Ki": 1.0}
        fmu.setupExperiment(startTime=0.0)
        fmu.enterInitializationMode()
        fmu.setReal([vr[n] for n in gains], list(gains.values()))
        if scenario == "initial_speed":
            fmu.setReal([vr["omega_L"]], [0.3])
        fmu.exitInitializationMode()
        # Steps short against each rig's contact period, so that switches fall inside steps.
        h = 1e-3 if shaft else 1e-5
        t, x_c = 0.0, 0.0
        for i in range(STEPS):
            if scenario == "open":
                tau = math.sin(7 * t) if shaft else 0.05 * math.sin(300 * t)
                fmu.setReal([vr["tau_m"], vr["tau_L"]], [tau, -0.1 * tau])
            elif scenario == "ramp":
                if i % 100 == 0:
                    fmu.setRealInputDerivatives([vr["tau_m"]], [1], [(-1) ** (i // 100) * 3.0])
            elif scenario == "closed":
                ref = math.sin(5 * t) if shaft else 10 * math.sin(500 * t)
                e = ref - fmu.getReal([vr["omega_m"]])[0]
                fmu.setReal([vr["tau_m"]], [gains["Kp"] * e + gains["Ki"] * x_c])
                x_c += h * e
            fmu.doStep(t, h)
            t += h
            values = list(fmu.getReal(reals)) + list(fmu.getRealOutputDerivatives(derived, [1] * len(derived)))
            contact = fmu.getInteger([vr["contact"]])[0]
            lines.append(" ".join(float(x).hex() for x in values) + f" {contact}")
        fmu.terminate()
    finally:
        fmu.freeInstance()
        shutil.rmtree(unzipdir, ignore_errors=True)
    return lines


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("fmu_dir", help="directory holding the FMI 2.0 archives (target/fmu)")
    parser.add_argument("--dump", help="write the recorded values to this file")
    args = parser.parse_args(argv)
    archives = sorted(Path(args.fmu_dir).glob("*.fmu"))
    if not archives:
        print(f"error: no .fmu archive in {args.fmu_dir} (build them with `cargo xtask fmu`)", file=sys.stderr)
        return 2
    lines = []
    for archive in archives:
        model = read_model_description(str(archive)).coSimulation.modelIdentifier
        own = [line for scenario in SCENARIOS for line in run(str(archive), model, scenario)]
        digest = hashlib.sha256(("\n".join(own) + "\n").encode()).hexdigest()
        print(f"{digest}  {model} ({len(own)} lines: {len(SCENARIOS)} scenarios)")
        lines += own
    text = "\n".join(lines) + "\n"
    if args.dump:
        with open(args.dump, "w") as f:
            f.write(text)
    print(f"{hashlib.sha256(text.encode()).hexdigest()}  all {len(archives)} models")
    return 0


if __name__ == "__main__":
    sys.exit(main())

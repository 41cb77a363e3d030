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
every Real variable, each mesh's contact and the output derivatives of the Real outputs, as exact
hexadecimal floats (`--dump` writes them, one line per step).

The archives are driven through the package's driver, backlash_fmu.fmu (each scenario on an
unpacked copy of its own); fmi2SetRealInputDerivatives and fmi2GetRealOutputDerivatives, which
the driver does not wrap, are called on its instance's fmpy object (`fmu`).
"""

from __future__ import annotations

import argparse
import hashlib
import math
import sys
from pathlib import Path

from backlash_fmu import fmu

SCENARIOS = ("open", "ramp", "closed", "initial_speed")
STEPS = 1500
# The outputs whose derivatives are recorded, those of them a model has: a single gap's, then a
# gearbox's intermediate shaft and meshes.
DERIVED = ["omega_m", "omega_L", "theta_m", "theta_L", "psi", "bound", "bound_paper", "theta_i", "omega_i", "psi_1",
           "psi_2"]


def run(path: Path, scenario: str) -> list[str]:
    """The lines of one scenario on the FMI 2.0 archive at `path`: its header, then one line per
    step."""
    with fmu.Archive(path) as archive:
        lines = [f"# {archive.model} {scenario}"]
        vr = archive.vr
        reals = [v.name for v in archive.md.modelVariables if v.type == "Real"]
        derived = [vr[n] for n in DERIVED if n in vr]
        # The rig's time scale follows the compliant member: a shaft's k (a gearbox's k_1), or a
        # belt's K_b.
        shaft = "k" in vr or "k_1" in vr
        gains = {"Kp": 5.0, "Ki": 10.0} if shaft else {"Kp": 0.05, "Ki": 1.0}
        start = dict(gains, omega_L=0.3) if scenario == "initial_speed" else gains
        inst = archive.co_simulation(name="fingerprint", params=start)
        try:
            slave = inst.fmu  # fmpy's FMU2Slave, for the input and output derivatives
            # Steps short against each rig's contact period, so that switches fall inside steps.
            h = 1e-3 if shaft else 1e-5
            t, x_c = 0.0, 0.0
            for i in range(STEPS):
                if scenario == "open":
                    tau = math.sin(7 * t) if shaft else 0.05 * math.sin(300 * t)
                    inst.set({"tau_m": tau, "tau_L": -0.1 * tau})
                elif scenario == "ramp":
                    if i % 100 == 0:
                        slave.setRealInputDerivatives([vr["tau_m"]], [1], [(-1) ** (i // 100) * 3.0])
                elif scenario == "closed":
                    ref = math.sin(5 * t) if shaft else 10 * math.sin(500 * t)
                    e = ref - inst.get("omega_m")[0]
                    inst.set({"tau_m": gains["Kp"] * e + gains["Ki"] * x_c})
                    x_c += h * e
                inst.do_step(t, h)
                t += h
                values = list(inst.get(*reals)) + list(slave.getRealOutputDerivatives(derived, [1] * len(derived)))
                contacts = " ".join(str(c) for c in inst.contacts().values())
                lines.append(" ".join(float(x).hex() for x in values) + f" {contacts}")
        finally:
            inst.free()
    return lines


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("fmu_dir", help="directory holding the FMI 2.0 archives (target/fmu)")
    parser.add_argument("--dump", help="write the recorded values to this file")
    args = parser.parse_args(argv)
    manifest = Path(args.fmu_dir) / "models.txt"
    if not manifest.is_file():
        print(f"error: no models.txt in {args.fmu_dir} (build the archives with `cargo xtask fmu`)", file=sys.stderr)
        return 2
    # The plants, as the manifest lists them.
    archives = sorted(Path(args.fmu_dir) / f"{model}.fmu" for model in manifest.read_text().split())
    lines = []
    for archive in archives:
        own = [line for scenario in SCENARIOS for line in run(archive, scenario)]
        model = own[0].split()[1]
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

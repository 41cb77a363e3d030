"""Design a drive, then simulate it: the backlash the design study allows, checked in closed loop.

1. `backlash_fmu.design` answers: for the paper's shaft rig under the best-damped PI loop on the
   motor speed, the largest half gap `delta_max` that keeps the load speed within `accuracy` of
   the same drive without backlash, whatever the reference (docs/design-a-drive.md).
2. Two instances of the BacklashShaft FMU, one with Delta = delta_max and one with Delta = 0, run
   under that PI loop, closed here in Python at every communication step, with a reversing
   reference: the measured deviation max |omega_L(with) - omega_L(without)| stays within the
   accuracy, and within the FMU's own guarantee `bound_sup`.

    python examples/design_then_simulate.py [--accuracy 0.02] [--horizon 5]
"""

import argparse
import math

import backlash_fmu
from backlash_fmu import fmu

parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
parser.add_argument("--accuracy", type=float, default=0.02, help="load-speed accuracy [m/s]")
parser.add_argument("--horizon", type=float, default=5.0, help="simulated time [s]")
args = parser.parse_args()

# 1. The design answer (the same numbers as `backlash design --accuracy 0.02 --json`).
answer = backlash_fmu.design("shaft", accuracy=args.accuracy)
plant = {name: value for name, value in answer["plant"].items() if name != "form"}
kp, ki, delta = answer["Kp"], answer["Ki"], answer["delta_max"]
print(f"design: delta_max = {delta:.4e} (half gap), Kp = {kp:.3f}, Ki = {ki:.3f}")

# The reference reverses at the closed loop's natural frequency, where the backlash hurts most.
frequency = sum(math.hypot(re, im) for re, im in answer["poles"]) / len(answer["poles"]) / (2 * math.pi)
def reference(t):
    return 0.05 * math.sin(2 * math.pi * frequency * t)

# 2. The twin drives: the FMU with the designed backlash and with none, from rest.
h = 1e-3  # communication step [s]: the PI loop samples the motor speed and holds the torque
with fmu.Archive(backlash_fmu.fmu_path("BacklashShaft")) as archive:
    drives = {gap: archive.co_simulation(f"Delta={gap}", dict(plant, Delta=gap, Kp=kp, Ki=ki))
              for gap in (delta, 0.0)}
    integral = {gap: 0.0 for gap in drives}
    worst = 0.0
    for n in range(round(args.horizon / h)):
        t = n * h
        for gap, drive in drives.items():
            omega_m, = drive.get("omega_m")
            error = reference(t) - omega_m                  # the sampled PI law
            drive.step(t, h, tau_m=kp * error + ki * integral[gap])
            integral[gap] += h * error
        (with_backlash,), (without,) = (drive.get("omega_L") for drive in drives.values())
        worst = max(worst, abs(with_backlash - without))
    bound_sup, = drives[delta].get("bound_sup")  # the FMU's guarantee for these parameters
    for drive in drives.values():
        drive.free()

print(f"max |omega_L(Delta) - omega_L(0)| over {args.horizon} s = {worst:.4e} m/s")
print(f"bound_sup = {bound_sup:.4e} m/s, accuracy = {args.accuracy} m/s")
assert worst <= bound_sup <= args.accuracy * (1 + 1e-9), "the design's guarantee does not hold"
print("the designed drive meets the accuracy")

"""A tolerance sweep on a local Dask cluster: how many drives of a production line meet the
speed accuracy when the backlash, the stiffness and the load vary (docs/sweep-tolerances.md).

Each sample draws a BacklashShaft drive from the tolerances below and runs it twice under the
design's PI loop, with its backlash and without, closed through fmpy; the deviation of the load
speed is compared with the accuracy and with the FMU's guarantee `bound_sup`. The samples run on
a Dask LocalCluster of `--workers` processes on this machine; the table and the summary go to
`--out`.

    python examples/local_sweep.py [--samples 200] [--workers 2] [--horizon 1.5] [--out results/local_sweep]
"""

import argparse
import json
import tempfile
from pathlib import Path

from backlash_fmu import sweep

# The tolerances, as a sweep config (TOML; every entry is optional, see the sweep's page).
CONFIG = """
model = "shaft"
[parameters]
Delta = {{ low = 0.5e-3, high = 3e-3 }}   # half gap [m]: a new gear pair to a worn one
k = {{ nominal = 200.0, tol = 0.10 }}      # stiffness [N/m], +-10 %
J_L = {{ nominal = 2.55, tol = 0.05 }}     # load inertia [kg], +-5 %
[run]
horizon = {horizon}
accuracy = 0.02                            # required load-speed accuracy [m/s]
"""


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--samples", type=int, default=200, help="drives drawn")
    parser.add_argument("--workers", type=int, default=2, help="worker processes of the LocalCluster")
    parser.add_argument("--horizon", type=float, default=1.5, help="simulated time of each run [s]")
    parser.add_argument("--out", type=Path, default=Path("results/local_sweep"), help="output directory")
    args = parser.parse_args()

    with tempfile.TemporaryDirectory() as tmp:
        config = Path(tmp) / "sweep.toml"
        config.write_text(CONFIG.format(horizon=args.horizon))
        # The same as `backlash sweep --samples N --seed 1 --workers W --config FILE --out DIR`:
        # it starts the LocalCluster, runs the samples in tasks, stops the cluster.
        status = sweep.main(["--samples", str(args.samples), "--seed", "1", "--workers", str(args.workers),
                             "--config", str(config), "--out", str(args.out), "--no-progress"])
    if status != 0:
        raise SystemExit(f"the sweep failed (exit status {status})")

    summary = json.loads((args.out / "summary.json").read_text())
    print(f"{summary['meeting_accuracy']} of {summary['samples']} drives meet the accuracy "
          f"({100 * summary['fraction_meeting_accuracy']:.1f} %); worst deviation / bound_sup = "
          f"{summary['worst_ratio']:.3f} (the bound holds: {summary['bound_holds']})")
    print("samples per worker:", sorted(summary["execution"]["samples_per_worker"].values()))


# The guard matters: Dask starts its worker processes by importing this file again.
if __name__ == "__main__":
    main()

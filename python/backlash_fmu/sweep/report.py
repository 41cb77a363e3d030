"""What a sweep writes: the table (one row per sample), the summary, and two plots."""

from __future__ import annotations

import csv
import json
import math
from pathlib import Path
from typing import Any

from .config import PARAMETERS, Config

COLUMNS = ("sample", *PARAMETERS, "max_dev", "bound_sup", "ratio", "meets")


def _cell(value: object) -> str:
    # repr: the shortest text that reads back as the same float, so tables compare byte for byte.
    if isinstance(value, bool):
        return "true" if value else "false"
    return repr(value)


def write_table(path: Path, rows: list[dict]) -> None:
    with path.open("w", newline="") as f:
        w = csv.writer(f, lineterminator="\n")
        w.writerow(COLUMNS)
        for row in sorted(rows, key=lambda r: r["sample"]):
            w.writerow([_cell(row[c]) for c in COLUMNS])


def summarize(rows: list[dict], config: Config, seed: int) -> dict[str, Any]:
    n = len(rows)
    meeting = sum(r["meets"] for r in rows)
    worst = max(rows, key=lambda r: r["ratio"])
    largest = max(rows, key=lambda r: r["max_dev"])
    return {
        "samples": n,
        "seed": seed,
        "accuracy": config.accuracy,
        "meeting_accuracy": meeting,
        "fraction_meeting_accuracy": meeting / n,
        "worst_ratio": worst["ratio"],
        "worst_ratio_sample": worst["sample"],
        "largest_max_dev": largest["max_dev"],
        "largest_max_dev_sample": largest["sample"],
        # max_dev / bound_sup above 1 would contradict the bound (docs/model.md §3).
        "bound_holds": all(r["ratio"] <= 1.0 for r in rows),
        "distributions": {name: d.describe() for name, d in config.distributions.items()},
        "settings": config.settings(),
        "config": config.source,
    }


def _finish(fig: Any, ax: Any, path: Path, legend_size: int) -> Path:
    """Legend, grid and layout of a figure, written to `path` and closed."""
    import matplotlib.pyplot as plt

    ax.legend(fontsize=legend_size)
    ax.grid(alpha=0.3)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path


def plot(out: Path, rows: list[dict], config: Config) -> list[Path]:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    import numpy as np

    eps = config.accuracy
    dev = np.array([r["max_dev"] for r in rows])
    delta = np.array([r["Delta"] for r in rows])
    sup = np.array([r["bound_sup"] for r in rows])
    meets = np.array([r["meets"] for r in rows])
    paths = []

    fig, ax = plt.subplots(figsize=(7.5, 4.5))
    bins = max(10, min(60, int(math.sqrt(len(rows))) * 2))
    ax.hist(dev * 1e3, bins=bins, color="C0", alpha=0.85)
    ax.axvline(eps * 1e3, color="k", ls="--", lw=1.2, label=f"ε = {eps:g} m/s")
    ax.set_xlabel("max |ω_L^b − ω_L^0| over the run [mm/s]")
    ax.set_ylabel("samples")
    ax.set_title(f"{len(rows)} drives: {meets.mean() * 100:.1f} % meet ε", fontsize=10)
    paths.append(_finish(fig, ax, out / "histogram.png", legend_size=9))

    fig, ax = plt.subplots(figsize=(7.5, 4.8))
    ax.scatter(delta[meets] * 1e3, dev[meets] * 1e3, s=10, color="C0", label="max deviation (meets ε)")
    ax.scatter(delta[~meets] * 1e3, dev[~meets] * 1e3, s=10, color="C3", label="max deviation (misses ε)")
    ax.scatter(delta * 1e3, sup * 1e3, s=6, marker="_", color="C2", label="bound_sup of the sample")
    # bound_sup is proportional to Delta at fixed k, J_L: the line uses the largest slope drawn.
    grid = np.linspace(0.0, delta.max() * 1.02, 50)
    slope = float(np.max(sup / np.where(delta > 0, delta, np.inf)))
    ax.plot(grid * 1e3, slope * grid * 1e3, color="C2", lw=1.2, label="bound_sup, worst k and J_L drawn")
    ax.axhline(eps * 1e3, color="k", ls="--", lw=1.0, label=f"ε = {eps:g} m/s")
    ax.set_xlabel("half gap Δ [mm]")
    ax.set_ylabel("load-speed deviation [mm/s]")
    ax.set_title("max deviation against Δ, with the bound", fontsize=10)
    paths.append(_finish(fig, ax, out / "deviation_vs_delta.png", legend_size=8))
    return paths


def write_summary(path: Path, summary: dict[str, Any]) -> None:
    # JSON has no infinity (a ratio with bound_sup = 0): such numbers are written as null.
    def finite(value: Any) -> Any:
        if isinstance(value, float) and not math.isfinite(value):
            return None
        if isinstance(value, dict):
            return {k: finite(v) for k, v in value.items()}
        return value

    path.write_text(json.dumps(finite(summary), indent=2, allow_nan=False) + "\n")

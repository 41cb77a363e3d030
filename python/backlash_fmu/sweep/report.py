"""What a sweep writes: the table (one row per sample), the summary (`summarize`, printed by
`describe`, a contradicted bound by `violation`) and the plots (`plot`: two, four on the web
line), for every model (config.MODELS)."""

from __future__ import annotations

import json
import math
from pathlib import Path
from typing import Any

from .config import PARAMETERS, Config

COLUMNS = ("sample", *PARAMETERS, "max_dev", "bound_sup", "ratio", "meets")


def write_table(path: Path, rows: list[dict]) -> None:
    """A whole table at once, in sample order, its columns those of the rows. The command line
    writes the table as the rows arrive instead: table.py (Writer, finish), the same bytes."""
    from .table import write_table as write

    write(path, rows)


# Units of each model's figures: (speed unit, speed scale and unit of the plots, Delta's scale
# and unit in the plots, what a sample is called).
_UNITS = {
    "shaft": ("m/s", 1e3, "mm/s", 1e3, "mm", "drives"),
    "belt": ("rad/s", 1.0, "rad/s", 1e6, "µm", "drives"),
    "web": ("rad/s", 1.0, "rad/s", 1e6, "µm", "web lines"),
}


def _model(config: Config) -> str:
    return getattr(config, "model", "shaft")


def summarize(rows: list[dict], config: Config, seed: int) -> dict[str, Any]:
    """The summary of a sweep's rows: the fraction meeting the accuracy, the worst
    max_dev/bound_sup, the largest max_dev (shaft: the sweep's original keys, plus "model");
    on the web line also the tension's: the fraction meeting eps_T, the worst
    max_dev_T/bound_T_sup and the largest max_dev_T. Without a speed accuracy (web)
    meeting_accuracy and fraction_meeting_accuracy are None. "bound_holds": no ratio (nor
    ratio_T) above 1."""
    n = len(rows)
    model = _model(config)
    speed_eps = config.accuracy is not None
    meeting = sum(r["meets"] for r in rows) if speed_eps else None
    worst = max(rows, key=lambda r: r["ratio"])
    largest = max(rows, key=lambda r: r["max_dev"])
    summary: dict[str, Any] = {
        "samples": n,
        "seed": seed,
        "accuracy": config.accuracy,
        "meeting_accuracy": meeting,
        "fraction_meeting_accuracy": meeting / n if speed_eps else None,
        "worst_ratio": worst["ratio"],
        "worst_ratio_sample": worst["sample"],
        "largest_max_dev": largest["max_dev"],
        "largest_max_dev_sample": largest["sample"],
        # max_dev / bound_sup above 1 would contradict the bound (docs/model.md §3).
        "bound_holds": all(r["ratio"] <= 1.0 for r in rows),
    }
    if model == "web":
        meeting_t = sum(r["meets_T"] for r in rows)
        worst_t = max(rows, key=lambda r: r["ratio_T"])
        largest_t = max(rows, key=lambda r: r["max_dev_T"])
        speed_holds = summary["bound_holds"]
        tension_holds = all(r["ratio_T"] <= 1.0 for r in rows)
        summary.update({
            "tension_accuracy": config.tension_accuracy,
            "meeting_tension_accuracy": meeting_t,
            "fraction_meeting_tension_accuracy": meeting_t / n,
            "worst_ratio_T": worst_t["ratio_T"],
            "worst_ratio_T_sample": worst_t["sample"],
            "largest_max_dev_T": largest_t["max_dev_T"],
            "largest_max_dev_T_sample": largest_t["sample"],
            # Either ratio above 1 would contradict its bound (docs/model.md §8).
            "speed_bound_holds": speed_holds,
            "tension_bound_holds": tension_holds,
            "bound_holds": speed_holds and tension_holds,
        })
    summary.update({
        "distributions": {name: d.describe() for name, d in config.distributions.items()},
        "settings": config.settings(),
        "config": config.source,
    })
    summary["model"] = model
    return summary


def describe(summary: dict[str, Any]) -> list[str]:
    """What the command prints about a summary's figures, one line each: the accuracy met, the
    largest deviation and the worst ratio (the shaft's two lines as the sweep has always printed
    them), and the web line's tension figures."""
    model = summary.get("model", "shaft")
    unit = _UNITS[model][0]
    n = summary["samples"]
    lines = []
    if summary["accuracy"] is not None:
        lines.append(f"accuracy ε = {summary['accuracy']:g} {unit} met by {summary['meeting_accuracy']}/{n} "
                     f"({summary['fraction_meeting_accuracy'] * 100:.1f} %)")
    lines.append(f"largest max deviation {summary['largest_max_dev']:.6g} {unit} "
                 f"(sample {summary['largest_max_dev_sample']}); "
                 f"worst max_dev/bound_sup = {summary['worst_ratio']:.4f} (sample {summary['worst_ratio_sample']})")
    if model == "web":
        lines.append(f"tension accuracy ε_T = {summary['tension_accuracy']:g} N met by "
                     f"{summary['meeting_tension_accuracy']}/{n} "
                     f"({summary['fraction_meeting_tension_accuracy'] * 100:.1f} %)")
        lines.append(f"largest max tension deviation {summary['largest_max_dev_T']:.6g} N "
                     f"(sample {summary['largest_max_dev_T_sample']}); worst max_dev_T/bound_T_sup = "
                     f"{summary['worst_ratio_T']:.4f} (sample {summary['worst_ratio_T_sample']})")
    return lines


def violation(summary: dict[str, Any]) -> str | None:
    """The one-line error when a deviation exceeds its bound (exit status 1), else None; the
    shaft's line as the sweep has always printed it."""
    if summary["bound_holds"]:
        return None
    if summary.get("speed_bound_holds", True) is False or summary.get("model", "shaft") != "web":
        return (f"max_dev/bound_sup = {summary['worst_ratio']!r} > 1 in sample {summary['worst_ratio_sample']}: "
                "the deviation exceeds the bound")
    return (f"max_dev_T/bound_T_sup = {summary['worst_ratio_T']!r} > 1 in sample {summary['worst_ratio_T_sample']}: "
            "the tension deviation exceeds the bound")


def _finish(fig: Any, ax: Any, path: Path, legend_size: int) -> Path:
    """Legend, grid and layout of a figure, written to `path` and closed."""
    import matplotlib.pyplot as plt

    if ax.get_legend_handles_labels()[0]:
        ax.legend(fontsize=legend_size)
    ax.grid(alpha=0.3)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path


def _histogram(path: Path, dev: Any, eps: float | None, scale: float, unit: str, eps_unit: str, xlabel: str,
               title: str, eps_name: str = "ε") -> Path:
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(7.5, 4.5))
    bins = max(10, min(60, int(math.sqrt(len(dev))) * 2))
    ax.hist(dev * scale, bins=bins, color="C0", alpha=0.85)
    if eps is not None:
        ax.axvline(eps * scale, color="k", ls="--", lw=1.2, label=f"{eps_name} = {eps:g} {eps_unit}")
    ax.set_xlabel(f"{xlabel} [{unit}]")
    ax.set_ylabel("samples")
    ax.set_title(title, fontsize=10)
    return _finish(fig, ax, path, legend_size=9)


def _against_delta(path: Path, delta: Any, dev: Any, sup: Any, meets: Any, eps: float | None, scales: tuple,
                   labels: dict[str, str]) -> Path:
    import matplotlib.pyplot as plt
    import numpy as np

    d_scale, d_unit, scale, unit, eps_unit = scales
    fig, ax = plt.subplots(figsize=(7.5, 4.8))
    if meets is None:
        ax.scatter(delta * d_scale, dev * scale, s=10, color="C0", label=labels["dev"])
    else:
        ax.scatter(delta[meets] * d_scale, dev[meets] * scale, s=10, color="C0",
                   label=f"{labels['dev']} (meets {labels['eps']})")
        ax.scatter(delta[~meets] * d_scale, dev[~meets] * scale, s=10, color="C3",
                   label=f"{labels['dev']} (misses {labels['eps']})")
    ax.scatter(delta * d_scale, sup * scale, s=6, marker="_", color="C2", label=f"{labels['sup']} of the sample")
    # The bound is proportional to Delta at fixed other parameters: the line uses the largest
    # slope drawn.
    grid = np.linspace(0.0, delta.max() * 1.02, 50)
    slope = float(np.max(sup / np.where(delta > 0, delta, np.inf)))
    ax.plot(grid * d_scale, slope * grid * scale, color="C2", lw=1.2, label=f"{labels['sup']}, {labels['worst']}")
    if eps is not None:
        ax.axhline(eps * scale, color="k", ls="--", lw=1.0, label=f"{labels['eps']} = {eps:g} {eps_unit}")
    ax.set_xlabel(f"half gap Δ [{d_unit}]")
    ax.set_ylabel(f"{labels['ylabel']} [{unit}]")
    ax.set_title(labels["title"], fontsize=10)
    return _finish(fig, ax, path, legend_size=8)


def plot(out: Path, rows: list[dict], config: Config) -> list[Path]:
    """The plots of a sweep, written under `out`: histogram.png (the max load-speed deviations,
    with ε) and deviation_vs_delta.png (max deviation and bound_sup against Δ); on the web line
    also tension_histogram.png and tension_vs_delta.png (max_dev_T and bound_T_sup, with ε_T)."""
    import matplotlib

    matplotlib.use("Agg")
    import numpy as np

    model = _model(config)
    eps_unit, scale, unit, d_scale, d_unit, what = _UNITS[model]
    eps = config.accuracy
    dev = np.array([r["max_dev"] for r in rows])
    delta = np.array([r["Delta"] for r in rows])
    sup = np.array([r["bound_sup"] for r in rows])
    meets = np.array([r["meets"] for r in rows]) if eps is not None else None
    title = f"{len(rows)} {what}: {meets.mean() * 100:.1f} % meet ε" if meets is not None else f"{len(rows)} {what}"
    worst = {"shaft": "worst k and J_L drawn", "belt": "worst K_b and J_L drawn",
             "web": "worst K_b, EA and L_w drawn"}[model]
    paths = [
        _histogram(out / "histogram.png", dev, eps, scale, unit, eps_unit, "max |ω_L^b − ω_L^0| over the run",
                   title),
        _against_delta(out / "deviation_vs_delta.png", delta, dev, sup, meets, eps,
                       (d_scale, d_unit, scale, unit, eps_unit),
                       {"dev": "max deviation", "eps": "ε", "sup": "bound_sup", "worst": worst,
                        "ylabel": "load-speed deviation", "title": "max deviation against Δ, with the bound"}),
    ]
    if model == "web":
        eps_t = config.tension_accuracy
        dev_t = np.array([r["max_dev_T"] for r in rows])
        sup_t = np.array([r["bound_T_sup"] for r in rows])
        meets_t = np.array([r["meets_T"] for r in rows])
        paths.append(_histogram(out / "tension_histogram.png", dev_t, eps_t, 1.0, "N", "N",
                                "max |T^b − T^0| over the run",
                                f"{len(rows)} {what}: {meets_t.mean() * 100:.1f} % meet ε_T", eps_name="ε_T"))
        paths.append(_against_delta(out / "tension_vs_delta.png", delta, dev_t, sup_t, meets_t, eps_t,
                                    (d_scale, d_unit, 1.0, "N", "N"),
                                    {"dev": "max tension deviation", "eps": "ε_T", "sup": "bound_T_sup",
                                     "worst": worst, "ylabel": "tension deviation",
                                     "title": "max tension deviation against Δ, with the bound"}))
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

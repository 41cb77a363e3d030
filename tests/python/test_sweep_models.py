"""The tolerance sweep of every model (backlash_fmu.sweep, `--model shaft|belt|web`): the belt's
and the web line's sweeps run (config, draws, twin.sample_row, summary, plots), three web rows
agree bit for bit with twin runs of BacklashWeb written out here, the config is validated per
model (also with the standard library only), and the defaults are the design answers'.

The twin runs written out here use backlash_fmu.fmu's instances directly, not backlash_fmu.twin:
they follow the sampling documented in `twin.twin_web_run` (and §3's speed loop for the belt),
with the same floating-point operations in the same order, so that agreement is exact.
"""

from __future__ import annotations

import math
import subprocess
import sys
from pathlib import Path

import pytest
from backlash_fmu import design, twin
from backlash_fmu.fmu import fmu_path
from backlash_fmu.sweep import config as sweep_config
from backlash_fmu.sweep import report

from archives import REPO, require
from test_sweep import STDLIB_ONLY  # the standard-library guard the check runs under

# Short runs keep the file at about ten seconds: the belt's 0.1 s default is short already; the
# web line's 0.5 s default is cut to 0.2 s, which still holds its largest tension deviation
# (near 0.15 s at the nominal line).
SEED = 11
BELT_SAMPLES = 6
WEB_SAMPLES = 4
WEB_HORIZON = 0.2

CHECK = REPO / "python" / "backlash_fmu" / "sweep" / "check.py"


def web_config(tmp_path: Path, extra: str = "") -> Path:
    path = tmp_path / "web.toml"
    path.write_text(f'model = "web"\n[run]\nhorizon = {WEB_HORIZON}\n{extra}')
    return path


@pytest.fixture(scope="module")
def web(tmp_path_factory):
    """The web sweep's config (defaults, shorter horizon), its draws and its rows."""
    cfg = sweep_config.load(web_config(tmp_path_factory.mktemp("web")))
    draws = cfg.draw(WEB_SAMPLES, SEED)
    rows = twin.sample_rows(require("BacklashWeb"), list(enumerate(draws)), cfg.settings())
    return cfg, draws, rows


@pytest.fixture(scope="module")
def belt():
    cfg = sweep_config.load(None, model="belt")
    draws = cfg.draw(BELT_SAMPLES, SEED)
    rows = twin.sample_rows(require("BacklashBelt"), list(enumerate(draws)), cfg.settings())
    return cfg, draws, rows


# ------------------------------------------------------------------------------------------
# Twin runs written out here, independently of backlash_fmu.twin
# ------------------------------------------------------------------------------------------


def hand_web_run(params: dict[str, float], settings: dict) -> dict[str, float]:
    """The twin web lines of docs/model.md §8 under the speed and tension PIs, sampled as
    `twin.twin_web_run`'s docstring says: two BacklashWeb instances (the drawn Delta and
    Delta = 0), the upstream web held at v_in = T_in = 0, every gain set on both; at t_i = i h the
    outputs are read, then (line with Delta first) e_T = T_ref - T, e = w_ref0(t_i) + Kp_T e_T +
    Ki_T x_T - omega_m, tau_m = Kp e + Ki x_c held over the step, x_c += h e, x_T += h e_T;
    w_ref0(t) = amplitude sin(2 pi frequency t). Returns the row's numbers."""
    archive = require("BacklashWeb")
    kp, ki, kp_t, ki_t = params["Kp"], params["Ki"], params["Kp_T"], params["Ki_T"]
    h, t_ref = settings["h"], settings["T_ref"]
    amplitude, frequency = settings["amplitude"], settings["frequency"]
    common = {name: params[name] for name in ("J_m", "J_L", "b_m", "b_L", "K_b", "R_1", "R_2", "R_g1", "R_g2",
                                              "R_w", "L_w", "EA", "v_ref")}
    common.update(Kp=kp, Ki=ki, Kp_T=kp_t, Ki_T=ki_t, v_in=0.0, T_in=0.0)
    lines = [archive.co_simulation(params=dict(common, Delta=params["Delta"])),
             archive.co_simulation(params=dict(common, Delta=0.0))]
    try:
        n = int(round(settings["horizon"] / h))
        x_c, x_t = [0.0, 0.0], [0.0, 0.0]
        dev = dev_t = 0.0
        for i in range(n + 1):
            t = i * h
            # Only the plant's outputs: the bounds are not read (they do not enter the plant).
            (T_b, w_m_b, w_L_b), (T_0, w_m_0, w_L_0) = (line.get("T", "omega_m", "omega_L") for line in lines)
            dev, dev_t = max(dev, abs(w_L_b - w_L_0)), max(dev_t, abs(T_b - T_0))
            if i == n:
                break
            for j, (line, T, w_m) in enumerate(((lines[0], T_b, w_m_b), (lines[1], T_0, w_m_0))):
                e_t = t_ref - T
                # The same operations in the same order as twin_web_run: exact agreement.
                e = amplitude * math.sin(2.0 * math.pi * frequency * t) + kp_t * e_t + ki_t * x_t[j] - w_m
                line.set({"tau_m": kp * e + ki * x_c[j]})
                line.do_step(t, h)
                x_c[j] += h * e
                x_t[j] += h * e_t
        sup_t, sup = lines[0].get("bound_T_sup", "bound_sup")
    finally:
        for line in lines:
            line.free()
    return {"max_dev": dev, "bound_sup": sup, "max_dev_T": dev_t, "bound_T_sup": sup_t}


def hand_belt_run(params: dict[str, float], settings: dict) -> dict[str, float]:
    """The twin belt drives under the PI on the motor speed (docs/model.md §3), sampled as
    `twin.twin_run` documents: e = w_ref(t_i) - omega_m, tau_m = Kp e + Ki x held, x += h e."""
    archive = require("BacklashBelt")
    kp, ki, h = params["Kp"], params["Ki"], settings["h"]
    amplitude, frequency = settings["amplitude"], settings["frequency"]
    common = {name: params[name] for name in ("J_m", "J_L", "b_m", "b_L", "K_b", "R_1", "R_2", "R_g1", "R_g2")}
    common.update(Kp=kp, Ki=ki)
    drives = [archive.co_simulation(params=dict(common, Delta=params["Delta"])),
              archive.co_simulation(params=dict(common, Delta=0.0))]
    try:
        n = int(round(settings["horizon"] / h))
        x = [0.0, 0.0]
        dev = 0.0
        for i in range(n + 1):
            t = i * h
            (w_m_b, w_L_b), (w_m_0, w_L_0) = (drive.get("omega_m", "omega_L") for drive in drives)
            dev = max(dev, abs(w_L_b - w_L_0))
            if i == n:
                break
            r = amplitude * math.sin(2.0 * math.pi * frequency * t)
            for j, (drive, w_m) in enumerate(((drives[0], w_m_b), (drives[1], w_m_0))):
                e = r - w_m
                drive.set({"tau_m": kp * e + ki * x[j]})
                drive.do_step(t, h)
                x[j] += h * e
        (sup,) = drives[0].get("bound_sup")
    finally:
        for drive in drives:
            drive.free()
    return {"max_dev": dev, "bound_sup": sup}


# ------------------------------------------------------------------------------------------
# The sweeps run
# ------------------------------------------------------------------------------------------


def test_three_web_rows_agree_bit_for_bit_with_twin_runs_written_out_here(web):
    """Rows 0, 1, 2 of the web sweep against twin runs of BacklashWeb written out above at the
    drawn parameters: the same arithmetic, so every number is equal, not merely close."""
    cfg, draws, rows = web
    settings = cfg.settings()
    assert settings["model"] == "web" and settings["horizon"] == WEB_HORIZON
    for index in range(3):
        row, params = rows[index], draws[index]
        assert row["sample"] == index and {name: row[name] for name in params} == params
        hand = hand_web_run(params, settings)
        for key, value in hand.items():
            assert row[key] == value, (index, key, row[key], value)
        assert row["ratio"] == hand["max_dev"] / hand["bound_sup"]
        assert row["ratio_T"] == hand["max_dev_T"] / hand["bound_T_sup"]
        assert row["meets_T"] == (hand["max_dev_T"] <= cfg.tension_accuracy)
        assert "meets" not in row  # no speed accuracy by default on the web line
    # The draws differ from sample to sample in what the web sweep draws.
    for name in ("Delta", "K_b", "EA", "L_w"):
        assert len({d[name] for d in draws[:3]}) == 3, name


def test_a_belt_row_agrees_bit_for_bit_with_a_twin_run_written_out_here(belt):
    cfg, draws, rows = belt
    hand = hand_belt_run(draws[0], cfg.settings())
    assert (rows[0]["max_dev"], rows[0]["bound_sup"]) == (hand["max_dev"], hand["bound_sup"])
    assert rows[0]["meets"] == (hand["max_dev"] <= cfg.accuracy)


def test_the_web_sweep_reports_tension_beside_speed(web, tmp_path):
    cfg, draws, rows = web
    assert cfg.columns() == ("sample", *sweep_config.PARAMETERS_OF["web"], "max_dev", "bound_sup", "ratio",
                             "max_dev_T", "bound_T_sup", "ratio_T", "meets_T")
    for row in rows:
        assert set(row) == set(cfg.columns())
        # The twin lines stay within both bounds (sampled loops: docs/model.md §3).
        assert 0 < row["ratio"] <= 1 and 0 < row["ratio_T"] <= 1, row
    summary = report.summarize(rows, cfg, SEED)
    assert summary["model"] == "web" and summary["samples"] == WEB_SAMPLES
    assert summary["tension_accuracy"] == cfg.tension_accuracy == 20.0
    assert summary["meeting_tension_accuracy"] == sum(r["meets_T"] for r in rows)
    assert summary["worst_ratio_T"] == max(r["ratio_T"] for r in rows)
    assert summary["largest_max_dev_T"] == max(r["max_dev_T"] for r in rows)
    assert summary["accuracy"] is None and summary["fraction_meeting_accuracy"] is None
    assert summary["bound_holds"] and summary["tension_bound_holds"] and report.violation(summary) is None
    lines = report.describe(summary)
    assert any(line.startswith("tension accuracy ε_T = 20 N met by") for line in lines), lines
    report.write_summary(tmp_path / "summary.json", summary)
    names = [p.name for p in report.plot(tmp_path, rows, cfg)]
    assert names == ["histogram.png", "deviation_vs_delta.png", "tension_histogram.png", "tension_vs_delta.png"]
    assert all((tmp_path / name).stat().st_size > 0 for name in names)


def test_a_web_speed_accuracy_adds_the_speed_criterion(tmp_path, web):
    cfg = sweep_config.load(web_config(tmp_path, "accuracy = 1.0\n"))
    assert cfg.accuracy == 1.0 and "meets" in cfg.columns()
    _, draws, rows = web
    row = twin.sample_row(require("BacklashWeb"), 0, draws[0], cfg.settings())
    # The same run as without the speed accuracy: only `meets` is added.
    assert {k: v for k, v in row.items() if k != "meets"} == rows[0]
    assert row["meets"] == (row["max_dev"] <= 1.0)
    summary = report.summarize([row], cfg, SEED)
    assert report.describe(summary)[0] == f"accuracy ε = 1 rad/s met by {int(row['meets'])}/1 " \
                                          f"({100.0 * row['meets']:.1f} %)"


def test_the_belt_sweep_runs(belt, tmp_path):
    cfg, draws, rows = belt
    assert cfg.archive == "BacklashBelt"
    assert cfg.columns() == ("sample", *sweep_config.PARAMETERS_OF["belt"], "max_dev", "bound_sup", "ratio", "meets")
    for row in rows:
        assert set(row) == set(cfg.columns())
        assert 0 < row["ratio"] <= 1, row
    summary = report.summarize(rows, cfg, SEED)
    assert summary["model"] == "belt" and summary["bound_holds"]
    assert summary["meeting_accuracy"] == sum(r["meets"] for r in rows)
    assert report.describe(summary)[0].startswith("accuracy ε = 2.2 rad/s met by ")
    names = [p.name for p in report.plot(tmp_path, rows, cfg)]
    assert names == ["histogram.png", "deviation_vs_delta.png"]


def test_sample_rows_is_sample_row_in_a_loop_and_the_shaft_needs_no_model_setting():
    """A chunk's rows are its samples' rows; settings without "model" (the sweep's callers before
    the models) run the shaft, as settings with model = "shaft" do."""
    cfg = sweep_config.load(None)
    settings = dict(cfg.settings(), horizon=0.2)
    assert settings.pop("model") == "shaft"
    draws = cfg.draw(3, SEED)
    archive = require("BacklashShaft")
    chunk = [(5, draws[0]), (2, draws[1])]
    rows = twin.sample_rows(archive, chunk, settings)
    assert rows == [twin.sample_row(archive, i, p, dict(settings, model="shaft")) for i, p in chunk]
    assert [r["sample"] for r in rows] == [5, 2]


def test_the_cli_runs_the_web_sweep_when_it_takes_model(tmp_path, web):
    """`python -m backlash_fmu.sweep --model web --serial` writes the library's rows (skipped until
    the command line takes --model)."""
    helped = subprocess.run([sys.executable, "-m", "backlash_fmu.sweep", "--help"], cwd=REPO, capture_output=True,
                            text=True, timeout=60)
    if "--model" not in helped.stdout:
        pytest.skip("the sweep's command line has no --model yet")
    cfg, _, rows = web
    done = subprocess.run([sys.executable, "-m", "backlash_fmu.sweep", "--model", "web", "--serial", "--no-progress",
                           "--samples", str(WEB_SAMPLES), "--seed", str(SEED), "--fmu", str(fmu_path("BacklashWeb")),
                           "--config", str(web_config(tmp_path)), "--out", str(tmp_path / "out")],
                          cwd=REPO, capture_output=True, text=True, timeout=120)
    assert done.returncode == 0, done.stderr
    lines = (tmp_path / "out" / "samples.csv").read_text().splitlines()
    assert lines[0].split(",") == list(cfg.columns())
    for line, row in zip(lines[1:], rows, strict=True):
        cells = line.split(",")
        for name, cell in zip(cfg.columns(), cells, strict=True):
            expected = row[name]
            assert (cell == ("true" if expected else "false")) if isinstance(expected, bool) else \
                float(cell) == expected, (name, cell, expected)


# ------------------------------------------------------------------------------------------
# Defaults
# ------------------------------------------------------------------------------------------


def test_the_belt_defaults_are_its_design_answers():
    d = design("belt", accuracy=sweep_config.BELT_ACCURACY)
    assert d == sweep_config.design_answer("belt")
    cfg = sweep_config.load(None, model="belt")
    plant, dist = d["plant"], cfg.distributions
    Fixed, Uniform = sweep_config.Fixed, sweep_config.Uniform
    for name in ("J_m", "b_m", "b_L", "R_1", "R_2", "R_g1", "R_g2"):
        assert dist[name] == Fixed(plant[name]), name
    assert dist["K_b"] == Uniform(plant["K_b"] * (1 - 0.15), plant["K_b"] * (1 + 0.15))
    assert dist["J_L"] == Uniform(plant["J_L"] * (1 - 0.05), plant["J_L"] * (1 + 0.05))
    assert dist["Delta"] == Uniform(25e-6, 100e-6)
    assert (dist["Kp"], dist["Ki"]) == (Fixed(d["Kp"]), Fixed(d["Ki"]))
    assert cfg.frequency == twin.reference_frequency(d["poles"]) and cfg.amplitude == twin.SPEED_AMPLITUDE
    assert (cfg.horizon, cfg.h, cfg.accuracy) == (0.1, 1e-4, d["accuracy"]) == (0.1, 1e-4, 2.2)
    # The design's delta_max lies inside the wear range: the sweep shows both sides of it.
    assert 25e-6 < d["delta_max"] < 100e-6


def test_the_web_defaults_are_its_design_answers_with_the_tension_gains_that_run():
    d = design("web", tension_accuracy=20, Kp_T=twin.KP_T, Ki_T=twin.KI_T)
    assert d == sweep_config.design_answer("web")
    cfg = sweep_config.load(None, model="web")
    plant, dist = d["plant"], cfg.distributions
    Fixed, Uniform = sweep_config.Fixed, sweep_config.Uniform
    for name in ("J_m", "J_L", "b_m", "b_L", "R_1", "R_2", "R_g1", "R_g2", "R_w", "v_ref"):
        assert dist[name] == Fixed(plant[name]), name
    for name, tol in (("K_b", 0.15), ("EA", 0.10), ("L_w", 0.05)):
        assert dist[name] == Uniform(plant[name] * (1 - tol), plant[name] * (1 + tol)), name
    assert dist["Delta"] == Uniform(25e-6, 100e-6)
    # The speed gains are the design's (which do not depend on the tension gains), the tension
    # gains the demo's web line's.
    assert (dist["Kp"], dist["Ki"]) == (Fixed(d["Kp"]), Fixed(d["Ki"]))
    assert d["Kp"] == design("web", tension_accuracy=20)["Kp"]
    assert (dist["Kp_T"], dist["Ki_T"]) == (Fixed(twin.KP_T), Fixed(twin.KI_T)) == (Fixed(d["Kp_T"]), Fixed(d["Ki_T"]))
    assert (cfg.amplitude, cfg.frequency, cfg.T_ref) == (twin.SPEED_AMPLITUDE, twin.SPEED_FREQUENCY, twin.T_REF)
    assert (cfg.horizon, cfg.h, cfg.accuracy, cfg.tension_accuracy) == (0.5, 1e-4, None, d["tension_accuracy"])
    # The answer's bound_T_sup is that of the loop the sweep runs: the FMU's at the nominal line
    # with these gains.
    params = {name: value for name, value in plant.items() if name != "form"}
    gains = dict(Kp=d["Kp"], Ki=d["Ki"], Kp_T=twin.KP_T, Ki_T=twin.KI_T)
    fmu_sup = twin.bound_t_sup(require("BacklashWeb"), dict(params, **gains))
    assert fmu_sup == pytest.approx(d["bound_T_sup_at_delta"], rel=1e-9)


def test_the_shaft_defaults_and_columns_are_the_sweeps_original_ones():
    cfg = sweep_config.load(None, model="shaft")
    assert cfg.model == "shaft" and cfg.archive == "BacklashShaft"
    assert cfg.columns() == report.COLUMNS
    assert sweep_config.load(None).distributions == cfg.distributions
    assert sweep_config.design_answer() == design("shaft", accuracy=0.02)


# ------------------------------------------------------------------------------------------
# Validation per model
# ------------------------------------------------------------------------------------------


@pytest.mark.parametrize("model, text, says", [
    ("belt", "[parameters]\nk = 200.0\n", "unknown parameter 'k' for the belt"),
    ("belt", "[parameters]\nEA = 1e5\n", "unknown parameter 'EA' for the belt"),
    ("shaft", "[parameters]\nEA = { nominal = 1e5, tol = 0.1 }\n", "unknown parameter 'EA' for the shaft"),
    ("shaft", "[parameters]\nL_w = 1.0\n", "a parameter of the web"),
    ("shaft", "[loop]\nKp_T = 0.01\n", "[loop]: unknown entry 'Kp_T'"),
    ("belt", "[run]\ntension_accuracy = 20.0\n", "[run]: unknown entry 'tension_accuracy' for the belt"),
    ("shaft", "[reference]\nT_ref = 2.0\n", "[reference]: unknown entry 'T_ref'"),
    ("web", "[parameters]\nk = 200.0\n", "unknown parameter 'k' for the web"),
    ("web", "[parameters]\nEA = { nominal = 1e5, tol = -0.1 }\n", "negative tolerance"),
    ("web", "[parameters]\nL_w = 0.0\n", "parameters.L_w: must be > 0"),
    ("web", "[loop]\nKi_T = { low = 0.06, high = 0.04 }\n", "inverted range"),
    ("web", "[run]\ntension_accuracy = 0.0\n", "run.tension_accuracy: must be > 0"),
    ("web", "[reference]\nT_ref = -1.0\n", "reference.T_ref: must be >= 0"),
    ("belt", 'model = "web"\n', "the config is for model = 'web' but --model belt was given"),
    (None, 'model = "gearbox"\n', "model = 'gearbox': choose one of shaft, belt, web"),
])
def test_a_bad_config_is_refused_per_model_in_one_line(tmp_path, model, text, says):
    """The same one-line error from the full load and from the check with the standard library
    only (what --check runs)."""
    path = tmp_path / "bad.toml"
    path.write_text(text)
    with pytest.raises(sweep_config.ConfigError) as loaded:
        sweep_config.load(path, model=model)
    with pytest.raises(sweep_config.ConfigError) as checked:
        sweep_config.load_checked(path, model=model)
    assert str(loaded.value) == str(checked.value)
    message = str(loaded.value)
    assert "\n" not in message and message.startswith(f"config {path}: ") and says in message, message


def test_the_model_comes_from_the_file_or_the_command_line(tmp_path):
    path = web_config(tmp_path)
    assert sweep_config.load(path).model == "web"
    assert sweep_config.load(path, model="web").model == "web"
    assert sweep_config.load(None, model="belt").model == "belt"
    assert sweep_config.load(None).model == "shaft"
    with pytest.raises(sweep_config.ConfigError, match="choose one of shaft, belt, web"):
        sweep_config.load(None, model="gearbox")


def test_the_check_by_path_takes_a_web_config_with_the_standard_library_only(tmp_path):
    """A config naming its model is checked for that model by check.py, standard library only:
    a good web config passes, a web-only parameter in a shaft config is refused in one line."""
    def check(config: Path) -> subprocess.CompletedProcess:
        return subprocess.run([sys.executable, "-I", "-c", STDLIB_ONLY, str(CHECK), "--samples", "2", "--seed", "1",
                               "--config", str(config), "--out", str(tmp_path / "out")], cwd=REPO,
                              capture_output=True, text=True, timeout=60)

    good = check(web_config(tmp_path, "tension_accuracy = 15.0\n"))
    assert good.returncode == 0 and good.stderr == "", good.stderr
    bad = tmp_path / "shaft.toml"
    bad.write_text('model = "shaft"\n[parameters]\nEA = 1e5\n')
    refused = check(bad)
    lines = refused.stderr.splitlines()
    assert refused.returncode == 2 and len(lines) == 1 and "unknown parameter 'EA' for the shaft" in lines[0], \
        refused.stderr
    assert not (tmp_path / "out").exists()

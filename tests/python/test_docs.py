"""The documentation against what it documents: every command line of the front page and the
user guide runs, every sweep config shown is one the sweep accepts, the SSP annotation shown is
the shipped one, and no text states a count of models, FMUs, archives or systems that the
description contradicts. (The Python blocks of the same pages run in `cargo xtask test`'s step 8,
xtask/src/python.rs; docs/fmu-reference.md is checked against the descriptions by
`cargo test -p xtask`.)

The command lines run with the interpreter's own `backlash` and `fmpy` commands (the venv's), in
a scratch directory: `backlash design ...` as shown; `backlash sweep ...` with `--check` (the
arguments, the config and the output directory checked; no sample runs, so that a sweep of
100 000 drives is checked in a second); `fmpy ...` on the archives under test, a path under
`target/fmu/` read as the same path in `backlash_fmu.fmu.archive_dir()`.
"""

from __future__ import annotations

import json
import os
import re
import shlex
import subprocess
import sys
from pathlib import Path

import pytest
from backlash_fmu.fmu import archive_dir

import archives
from archives import REPO

BIN = Path(sys.executable).parent

# The front page and the user guide: what a user reads first and copies.
PAGES = sorted(REPO.glob("README*.md")) + sorted((REPO / "docs").glob("*.md"))


def blocks(page: Path, language: str) -> list[str]:
    """The bodies of the fenced blocks of `page` whose info string is `language`."""
    found, body, inside = [], [], None
    for line in page.read_text().splitlines():
        if inside is None:
            if line.startswith("```"):
                inside = line[3:].strip()
                body = []
        elif line.rstrip() == "```":
            if inside == language:
                found.append("\n".join(body) + "\n")
            inside = None
        else:
            body.append(line)
    return found


def command_lines(prefix: str) -> list[tuple[str, list[str]]]:
    """(page, argv) of every line of a ```sh block that runs `prefix` (a leading `venv/bin/`
    read as the venv's own), its comment cut and its continuation lines joined."""
    found = []
    for page in PAGES:
        for block in blocks(page, "sh"):
            for line in block.replace("\\\n", " ").splitlines():
                words = shlex.split(line, comments=True)
                if words and words[0].removeprefix("venv/bin/") == prefix:
                    found.append((page.relative_to(REPO).as_posix(), [words[0].removeprefix("venv/bin/"), *words[1:]]))
    return found


BACKLASH = command_lines("backlash")
FMPY = command_lines("fmpy")


def run(argv: list[str], cwd: Path, timeout: float = 120) -> subprocess.CompletedProcess:
    # The archives under test, named absolutely: the command runs in another directory.
    env = dict(os.environ, BACKLASH_FMU_DIR=str(archive_dir().resolve())) if "BACKLASH_FMU_DIR" in os.environ \
        else None
    return subprocess.run([str(BIN / argv[0]), *argv[1:]], cwd=cwd, capture_output=True, text=True,
                          timeout=timeout, env=env)


def test_the_pages_show_commands_to_run():
    assert any(argv[1] == "design" for _, argv in BACKLASH)
    assert any(argv[1] == "sweep" for _, argv in BACKLASH)
    assert FMPY


def measured_run(path: Path) -> None:
    """The run a page's `backlash identify ... FILE` line reads, made in the scratch directory by
    the tests' own simulator (identify_data.py): BacklashShaft's default rig (the paper's,
    Δ = 0.775 mm) from rest with the teeth off centre, ±2 N.m reversing every 0.5 s plus a
    multisine, both speeds at 200 Hz with 1 mm/s of noise and 0.1 mm/s resolution, 4 s."""
    import identify_data

    params = {"J_m": 2.28, "J_L": 2.55, "b_m": 0.05, "b_L": 0.05, "k": 200.0, "Delta": 0.775e-3}
    h, n = 0.005, 801
    tau = identify_data.reversing_steps(n, h, 2.0, 1.0, multisine=1.0, seed=1)
    measured = identify_data.simulate("shaft", params, tau, h, 0.3 * params["Delta"])
    sensors = identify_data.Sensors(("omega_m", "omega_L"), speed_sigma=1e-3, speed_resolution=1e-4)
    identify_data.write_csv(path, identify_data.table(measured, sensors, seed=1))


@pytest.mark.parametrize("page,argv", BACKLASH, ids=[" ".join(argv[:4]) for _, argv in BACKLASH])
def test_backlash_command_lines_run(page, argv, tmp_path):
    if argv[1] == "sweep":
        argv = [*argv, "--check"]
    if argv[1] == "identify":
        files = [a for i, a in enumerate(argv[2:], 2) if a.endswith(".csv") and not argv[i - 1].startswith("--")]
        assert len(files) == 1, argv
        measured_run(tmp_path / files[0])
    done = run(argv, tmp_path)
    assert done.returncode == 0, f"{page}: `{shlex.join(argv)}` failed:\n{done.stdout}\n{done.stderr}"
    if argv[1] == "design":
        assert "delta_max" in done.stdout
        if "--json" in argv:
            assert json.loads(done.stdout)["delta_max"] > 0
    if argv[1] == "identify":
        assert "Delta" in done.stdout
        if "--json" in argv:
            answer = json.loads(done.stdout)
            assert answer["estimates"]["Delta"]["identifiable"] is True
            assert ("accuracy" in answer) == ("--accuracy" in argv)
    if argv[1] == "excite":
        out = tmp_path / argv[argv.index("--out") + 1]
        assert out.read_text().splitlines()[0] == "time,tau_m"


@pytest.mark.parametrize("page,argv", FMPY, ids=[" ".join(argv[:3]) for _, argv in FMPY])
def test_fmpy_command_lines_run(page, argv, tmp_path):
    argv = [str(archive_dir().resolve() / arg.removeprefix("target/fmu/")) if arg.startswith("target/fmu/")
            else arg for arg in argv]
    done = run(argv, tmp_path)
    assert done.returncode == 0, f"{page}: `{shlex.join(argv)}` failed:\n{done.stdout}\n{done.stderr}"
    if "--output-file" in argv:
        table = (tmp_path / argv[argv.index("--output-file") + 1]).read_text().splitlines()
        columns = table[0].replace('"', "").split(",")
        wanted = argv[argv.index("--output-variables") + 1:]
        wanted = wanted[:next((i for i, w in enumerate(wanted) if w.startswith("--")), len(wanted))]
        assert columns[0] == "time" and sorted(columns[1:]) == sorted(wanted) and len(table) > 100


CONFIGS = [(page.relative_to(REPO).as_posix(), block) for page in PAGES for block in blocks(page, "toml")]


def test_the_sweep_page_shows_its_configs():
    assert sum(page == "docs/sweep-tolerances.md" for page, _ in CONFIGS) >= 3


@pytest.mark.parametrize("page,config", CONFIGS, ids=[f"{p}:{i}" for i, (p, _) in enumerate(CONFIGS)])
def test_sweep_configs_shown_are_accepted(page, config, tmp_path):
    path = tmp_path / "config.toml"
    path.write_text(config)
    argv = ["backlash", "sweep", "--samples", "1", "--seed", "1", "--config", str(path), "--out", "out", "--check"]
    done = run(argv, tmp_path)
    assert done.returncode == 0, f"{page}: a config the sweep refuses:\n{config}\n{done.stderr}"


def test_the_ssp_annotation_shown_is_the_shipped_one():
    def squeezed(text: str) -> str:
        return re.sub(r"\s+", " ", re.sub(r">\s+<", "><", text)).strip()

    shown = [squeezed(block) for block in blocks(REPO / "docs" / "close-a-loop.md", "xml")]
    assert len(shown) == 1
    assert shown[0] in squeezed((REPO / "systems" / "sine" / "SystemStructure.ssd").read_text())


def anchors(page: Path) -> set[str]:
    """The anchors GitHub gives the headings of `page` (lower case, punctuation dropped, spaces as
    hyphens, a repeated one numbered)."""
    seen: dict[str, int] = {}
    found = set()
    inside = False
    for line in page.read_text().splitlines():
        if line.startswith("```"):
            inside = not inside
        if inside or not line.startswith("#"):
            continue
        slug = re.sub(r"[^\w\- ]", "", line.lstrip("#").strip().lower()).replace(" ", "-")
        found.add(slug if slug not in seen else f"{slug}-{seen[slug]}")
        seen[slug] = seen.get(slug, 0) + 1
    return found


def test_anchors_are_github_s():
    model = anchors(REPO / "docs" / "model.md")
    assert {"4-interface-of-the-fmus", "with-a-damper", "with-a-damper-1", "7-fmi-30"} <= model


@pytest.mark.parametrize("page", PAGES, ids=[p.relative_to(REPO).as_posix() for p in PAGES])
def test_links_lead_somewhere(page):
    """Every relative link of the page names a file of the repository, and its #anchor a heading
    of that page."""
    broken = []
    text = re.sub(r"^```.*?^```", "", page.read_text(), flags=re.DOTALL | re.MULTILINE)
    for target in re.findall(r"\]\(([^)\s]+)\)", text):
        if re.match(r"[a-z]+:", target):
            continue
        path, _, anchor = target.partition("#")
        file = (page.parent / path).resolve() if path else page
        if not file.exists():
            broken.append(target)
        elif anchor and file.suffix == ".md" and anchor not in anchors(file):
            broken.append(target)
    assert not broken, f"{page.relative_to(REPO)}: broken links {broken}"


# ---------------------------------------------------------------------------------------------
# Counts: no text states a number of models, FMUs, archives or systems that the description
# contradicts. The safest text states none; these checks catch the ones that do.
# ---------------------------------------------------------------------------------------------

WORDS = {"one": 1, "two": 2, "three": 3, "four": 4, "five": 5, "six": 6, "seven": 7, "eight": 8,
         "nine": 9, "ten": 10, "eleven": 11, "twelve": 12, "both": 2}
# A number, up to two words between, then what it counts ("three drive-train FMUs", "the six
# archives", "both models"). "FMI 2.0 archives" is no count: the number is a version.
COUNT = re.compile(r"(?<![\w.])(" + "|".join(WORDS) + r"|\d+)(?![\w.])((?:\s+[A-Za-z][\w-]*){0,2}?)\s+"
                   r"(models|plants|controllers|FMUs|archives|systems)\b", re.IGNORECASE)

# The texts a user or an importer reads: the front page, the user guide and the examples, the
# package's metadata and modules (their docstrings are its help), the FMUs' own documentation.
COUNTED = [
    *REPO.glob("README*.md"),
    *(REPO / "docs").glob("*.md"),
    *(REPO / "examples").glob("*.py"),
    REPO / "pyproject.toml",
    REPO / "Cargo.toml",
    *(REPO / "python").rglob("*.py"),
    *(REPO / "modelDescription" / "documentation").rglob("*.html"),
]


def expected_counts() -> dict[str, int]:
    """What the description says: its plants (`models.txt`) and controllers (`controllers.txt`),
    an FMI 2.0 and an FMI 3.0 archive of each, and the systems of systems/."""
    import backlash_fmu

    plants, controllers = len(archives.MODELS), len(archives.CONTROLLERS)
    assert (plants, controllers) == (len(backlash_fmu.MODELS), len(backlash_fmu.CONTROLLERS)) and plants
    return {"models": plants, "plants": plants, "controllers": controllers, "fmus": plants + controllers,
            "archives": 2 * (plants + controllers),
            "systems": len(list((REPO / "systems").glob("*/SystemStructure.ssd")))}


def stated_counts(text: str) -> list[tuple[str, int, str]]:
    """(phrase, number, noun) of every count stated in `text`."""
    found = []
    for match in COUNT.finditer(text):
        number, between, noun = match.groups()
        if between.split()[:1] == ["of"]:
            continue  # "one of the models" counts one, not the models
        value = WORDS.get(number.lower()) or int(number)
        noun = noun.lower()
        # A plant FMU or archive is counted among the plants ("three drive-train FMUs").
        if noun in ("fmus", "archives") and re.search(r"plant|drive", between, re.IGNORECASE):
            noun = "plants" if noun == "fmus" else "plant archives"
        found.append((" ".join(match.group(0).split()), value, noun))
    return found


def test_count_phrases_are_found():
    assert stated_counts("the six archives, three drive-train FMUs, both models, FMI 2.0 archives") == [
        ("six archives", 6, "archives"), ("three drive-train FMUs", 3, "plants"), ("both models", 2, "models")]
    assert stated_counts("FMI 3.0 archives, 1000 times, two drive trains, one of the models") == []


@pytest.mark.parametrize("path", COUNTED, ids=[p.relative_to(REPO).as_posix() for p in COUNTED])
def test_no_text_states_a_count_the_description_contradicts(path):
    expected = expected_counts()
    expected["plant archives"] = 2 * expected["plants"]
    wrong = []
    for phrase, value, noun in stated_counts(path.read_text()):
        allowed = {expected[noun]}
        if phrase.lower().startswith("both") and noun == "archives":
            allowed.add(2)  # a model's pair: its FMI 2.0 and its FMI 3.0 archive
        if value not in allowed:
            wrong.append(f"{phrase!r}: the description has {expected[noun]} {noun}")
    assert not wrong, f"{path.relative_to(REPO)}: " + "; ".join(wrong)

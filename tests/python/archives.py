"""The archives under test, unpacked once per session through backlash_fmu.fmu.

The archives and their manifest are those of `backlash_fmu.fmu.archive_dir()`: the folder
$BACKLASH_FMU_DIR (FMI 2.0 archives and models.txt in it, FMI 3.0 ones in its fmi3/, as
`cargo xtask fmu` writes them to target/fmu), else the package's own archives.
"""

from __future__ import annotations

import functools
from pathlib import Path

import pytest
from backlash_fmu.fmu import CONTROLLER_MANIFEST, Archive, fmu_path, models

REPO = Path(__file__).resolve().parents[2]

# Every packaged model, as the FMI 2.0 manifest lists them; () without a manifest (conftest.py then
# stops the run before any test).
MODELS = models()
# The controllers packaged beside them (controllers.txt).
CONTROLLERS = models(manifest=CONTROLLER_MANIFEST)

_extracted: list[Archive] = []


@functools.cache
def shared(model: str, fmi: int = 2) -> Archive:
    """The FMI 2.0 (`fmi=2`) or FMI 3.0 (`fmi=3`) archive of `model`, unpacked once per test
    session."""
    archive = Archive.of(model, fmi)
    _extracted.append(archive)
    return archive


def separate_copy(model: str, fmi: int = 2) -> Archive:
    """Another unpacked copy: its shared library is a different file, so the dynamic loader gives
    it its own code and data (a truly fresh instance)."""
    archive = Archive.of(model, fmi)
    _extracted.append(archive)
    return archive


def require(model: str, fmi: int = 2) -> Archive:
    """The shared copy. A missing archive fails the test, never skips it (conftest.py already
    stops the run before any test when an archive is missing)."""
    path = fmu_path(model, fmi)
    if not path.is_file():
        pytest.fail(f"FMU archive not found: {path} (build with `cargo xtask fmu`)")
    return shared(model, fmi)


def remove_all() -> None:
    """Deletes every unpacked copy (at the end of the session)."""
    shared.cache_clear()
    while _extracted:
        _extracted.pop().remove()


def real_outputs(model: str) -> tuple[str, ...]:
    """The Real outputs and calculated parameters of `model`, in value-reference order: its
    states, psi (a gearbox's psi_1, psi_2), the bounds, bound_sup."""
    md = shared(model).md
    keep = [v for v in md.modelVariables if v.type in ("Real", "Float64") and v.causality in ("output", "calculatedParameter")]
    return tuple(v.name for v in sorted(keep, key=lambda v: v.valueReference))


def contact_output(model: str) -> str:
    """The name of the contact output: `contact`, a gearbox's first mesh's `contact_1`."""
    names = {v.name for v in shared(model).md.modelVariables}
    return "contact" if "contact" in names else "contact_1"


def gap_parameters(model: str) -> tuple[str, ...]:
    """The half-gap parameters: `Delta`, a gearbox's `Delta_1` and `Delta_2`."""
    names = [v.name for v in shared(model).md.modelVariables if v.causality == "parameter"]
    return tuple(n for n in names if n == "Delta" or n.startswith("Delta_"))


def _single_gap(model: str) -> bool:
    return any(v.name == "psi" for v in shared(model).md.modelVariables)


# The models of one gap (docs/model.md §1), whose suites compare with the single gap's Python
# reference (reference.py); the two-stage gearbox (§10) has its own, test_two_stage.py.
SINGLE_GAP = tuple(m for m in MODELS if _single_gap(m))

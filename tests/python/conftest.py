"""pytest wiring: FMU fixtures, and a run without the packaged FMUs fails before any test."""

from __future__ import annotations

import os

# The tests multiply 4x4 and 5x5 matrices by the thousand: BLAS worker threads only add
# synchronisation cost (30x slower on a busy 2-core machine). Must precede the numpy import.
for _var in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

import pytest  # noqa: E402
from backlash_fmu.fmu import MANIFEST, Archive, archive_dir, fmu_path  # noqa: E402

import archives  # noqa: E402


def pytest_sessionstart(session):
    """The manifest and every archive it names, FMI 2.0 and FMI 3.0, must exist: skipping the
    tests that need them would let an unbuilt tree pass."""
    if not archives.MODELS:
        pytest.exit(f"model manifest not found or empty: {archive_dir() / MANIFEST} (build with `cargo xtask fmu`)",
                    returncode=1)
    paths = [fmu_path(model, fmi) for fmi in (2, 3) for model in archives.MODELS]
    missing = [str(path) for path in paths if not path.is_file()]
    if missing:
        pytest.exit(f"FMU archive not found: {', '.join(missing)} (build with `cargo xtask fmu`)", returncode=1)


@pytest.fixture(scope="session", autouse=True)
def _remove_extracted_fmus():
    yield
    archives.remove_all()


@pytest.fixture(scope="session")
def shaft() -> Archive:
    return archives.require("BacklashShaft")


@pytest.fixture(scope="session", params=archives.MODELS)
def fmu(request) -> Archive:
    """Each of the FMUs in turn (its FMI 2.0 archive)."""
    return archives.require(request.param)

"""pytest wiring: FMU fixtures, and a run without the packaged FMUs fails before any test."""

from __future__ import annotations

import os

# The tests multiply 4x4 and 5x5 matrices by the thousand: BLAS worker threads only add
# synchronisation cost (30x slower on a busy 2-core machine). Must precede the numpy import.
for _var in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

import pytest  # noqa: E402

import fmu_driver  # noqa: E402


def pytest_sessionstart(session):
    """The manifest and every archive it names must exist: skipping the tests that need them would
    let an unbuilt tree pass."""
    if not fmu_driver.MODELS:
        pytest.exit(f"model manifest not found or empty: {fmu_driver.manifest_path()} (build with `cargo xtask fmu`)",
                    returncode=1)
    missing = [str(path) for path in map(fmu_driver.fmu_path, fmu_driver.MODELS) if not path.is_file()]
    if missing:
        pytest.exit(f"FMU archive not found: {', '.join(missing)} (build with `cargo xtask fmu`)", returncode=1)


@pytest.fixture(scope="session", autouse=True)
def _remove_extracted_fmus():
    yield
    fmu_driver.remove_all()


@pytest.fixture(scope="session")
def shaft() -> fmu_driver.Extracted:
    return fmu_driver.require("BacklashShaft")


@pytest.fixture(scope="session", params=fmu_driver.MODELS)
def fmu(request) -> fmu_driver.Extracted:
    """Each of the FMUs in turn."""
    return fmu_driver.require(request.param)

"""The PEP 517 build backend of `backlash_fmu` (pyproject.toml): maturin's, after the FMU
archives are packed into the package.

Before a wheel is built, `cargo xtask fmu --out python/backlash_fmu/archives` builds the FMU
library from this workspace and writes the six archives (FMI 2.0 and FMI 3.0 of every model)
and their manifests there; maturin then builds the native module `backlash_fmu._native` and the
wheel, which carries them. The config setting `platforms` (`pip install . --config-settings
platforms=all`) packs the win64 and aarch64-linux libraries too (`--all-platforms`, which needs
the cross tools of README.md); the default is `linux64`.
"""

from __future__ import annotations

import shutil
import subprocess
import sys
from pathlib import Path
from typing import Any, Mapping

import maturin
from maturin import (  # noqa: F401  (the hooks taken as maturin has them)
    build_sdist,
    get_requires_for_build_sdist,
    get_requires_for_build_wheel,
    prepare_metadata_for_build_wheel,
)

ROOT = Path(__file__).resolve().parents[2]
ARCHIVES = ROOT / "python" / "backlash_fmu" / "archives"
PLATFORMS = {"linux64": [], "all": ["--all-platforms"]}


def _pack_archives(config_settings: Mapping[str, Any] | None) -> None:
    """The archives of every model, freshly packed (a model no longer built leaves none)."""
    platforms = (config_settings or {}).get("platforms", "linux64")
    if platforms not in PLATFORMS:
        raise ValueError(f"config setting platforms = {platforms!r}: choose {' or '.join(PLATFORMS)}")
    shutil.rmtree(ARCHIVES, ignore_errors=True)
    command = ["cargo", "xtask", "fmu", *PLATFORMS[platforms], "--out", str(ARCHIVES)]
    # pip shows a backend's stderr; stdout is its answer channel to some frontends.
    subprocess.run(command, cwd=ROOT, check=True, stdout=sys.stderr)


def _for_maturin(config_settings: Mapping[str, Any] | None) -> dict[str, Any] | None:
    rest = {k: v for k, v in (config_settings or {}).items() if k != "platforms"}
    return rest or None


def build_wheel(wheel_directory: str, config_settings: Mapping[str, Any] | None = None,
                metadata_directory: str | None = None) -> str:
    _pack_archives(config_settings)
    return maturin.build_wheel(wheel_directory, _for_maturin(config_settings), metadata_directory)


def build_editable(wheel_directory: str, config_settings: Mapping[str, Any] | None = None,
                   metadata_directory: str | None = None) -> str:
    _pack_archives(config_settings)
    return maturin.build_editable(wheel_directory, _for_maturin(config_settings), metadata_directory)

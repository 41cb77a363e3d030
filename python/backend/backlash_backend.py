"""The PEP 517 build backend of `backlash_fmu` (pyproject.toml): maturin's, after the FMU
archives are packed into the package, and an sdist that carries the whole workspace.

Before a wheel is built, `cargo xtask fmu --out python/backlash_fmu/archives` builds the FMU
library from this workspace and writes every model's archives (FMI 2.0 and FMI 3.0), the
manifests and the packed systems there; maturin then builds the native module
`backlash_fmu._native` and the wheel, which carries them. The config setting `platforms`
(`pip install . --config-settings platforms=all`) packs the win64 and aarch64-linux libraries
too (`--all-platforms`, which needs the cross tools of README.md); the default is `linux64`.

The sdist (`build_sdist`) is the workspace a wheel is built from: maturin's sdist takes only the
binding's crate and its path dependencies, and rewrites the workspace manifest to them, which
leaves out the FMU library, xtask (whose `cargo xtask fmu` packs the archives) and the systems.
So the sdist is written here: maturin's metadata (PKG-INFO) and every file of `SDIST`, the
workspace manifest unchanged. `pip install backlash_fmu-<version>.tar.gz` then builds as
`pip install .` does, where cargo is present.
"""

from __future__ import annotations

import gzip
import io
import shutil
import subprocess
import sys
import tarfile
import tempfile
import tomllib
from pathlib import Path
from typing import Any, Mapping

import maturin
from maturin import (  # noqa: F401  (the hooks taken as maturin has them)
    get_requires_for_build_sdist,
    get_requires_for_build_wheel,
    prepare_metadata_for_build_wheel,
)

ROOT = Path(__file__).resolve().parents[2]
ARCHIVES = ROOT / "python" / "backlash_fmu" / "archives"
PLATFORMS = {"linux64": [], "all": ["--all-platforms"]}
# What the sdist carries besides the workspace's members (Cargo.toml): the lock file, the xtask
# alias (.cargo/config.toml), the root crate's build script, sources and the bench its manifest
# names, the systems packed beside the archives, and the package's own files.
SDIST = ["Cargo.toml", "Cargo.lock", ".cargo", "build.rs", "src", "benches", "systems", "rustfmt.toml",
         "pyproject.toml", "README.md"]
# Never in the sdist: build products and caches.
NOT_IN_SDIST = {"__pycache__", "target", ".pytest_cache"}


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


def _sdist_files() -> list[Path]:
    """The files of the sdist, relative to the root, sorted: every file under `SDIST` and under
    each workspace member's folder, without caches, the packed archives or a built module."""
    members = tomllib.loads((ROOT / "Cargo.toml").read_text())["workspace"]["members"]
    files: set[Path] = set()
    for top in SDIST + [m for m in members if m != "."]:
        path = ROOT / top
        if not path.exists():
            raise FileNotFoundError(f"{path}: the sdist needs it")
        for file in [path] if path.is_file() else path.rglob("*"):
            relative = file.relative_to(ROOT)
            if (file.is_file() and not NOT_IN_SDIST & set(relative.parts) and file.suffix != ".pyc"
                    and ARCHIVES.relative_to(ROOT) not in relative.parents
                    and not (relative.parent == Path("python/backlash_fmu") and relative.name.startswith("_native"))):
                files.add(relative)
    return sorted(files)


def build_sdist(sdist_directory: str, config_settings: Mapping[str, Any] | None = None) -> str:
    """`<name>-<version>.tar.gz` in `sdist_directory`: maturin's PKG-INFO, then the workspace
    (`_sdist_files`) under `<name>-<version>/`; returns the file's name."""
    with tempfile.TemporaryDirectory() as scratch:
        name = maturin.build_sdist(scratch, config_settings)
        base = name.removesuffix(".tar.gz")
        with tarfile.open(Path(scratch) / name) as theirs:
            pkg_info = theirs.extractfile(f"{base}/PKG-INFO").read()

    def entry(arcname: str, size: int, mode: int, mtime: float) -> tarfile.TarInfo:
        info = tarfile.TarInfo(f"{base}/{arcname}")
        info.size, info.mode, info.mtime = size, mode, int(mtime)
        return info

    target = Path(sdist_directory) / name
    partial = target.with_name(name + ".partial")
    # Fixed owner, modes from the executable bit, the files' own times (a build from the unpacked
    # tree is then incremental as in the checkout).
    with open(partial, "wb") as raw, gzip.GzipFile(fileobj=raw, mode="wb", mtime=0) as zipped, \
            tarfile.open(fileobj=zipped, mode="w", format=tarfile.PAX_FORMAT) as tar:
        tar.addfile(entry("PKG-INFO", len(pkg_info), 0o644, 0), io.BytesIO(pkg_info))
        for relative in _sdist_files():
            file = ROOT / relative
            stat = file.stat()
            mode = 0o755 if stat.st_mode & 0o111 else 0o644
            with open(file, "rb") as content:
                tar.addfile(entry(relative.as_posix(), stat.st_size, mode, stat.st_mtime), content)
    partial.replace(target)
    return name

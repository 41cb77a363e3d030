"""The sweep's arguments, config and output directory checked with the standard library only:

    python3 path/to/backlash_fmu/sweep/check.py --samples N --seed S [--config FILE] [--out DIR] ...

runs `python -m backlash_fmu.sweep --check ...` without the package being installed or its
dependencies (numpy, fmpy, the compiled design study) being present: `cargo xtask sweep` runs it
with the base python3 before it builds anything, so that a bad config is refused in a second
with the sweep's own one `error:` line and exit status 2 (0 when everything is valid).

Run by path, this file loads the package's directory as a package of its own under a private
name (importlib, no sys.path entry), without backlash_fmu's __init__, and calls its `main` with
`--check`: the same parser and validation as the sweep itself.
"""

from __future__ import annotations

import importlib.util
import sys
from pathlib import Path

PRIVATE_NAME = "_backlash_fmu_sweep_check"


def run(argv: list[str]) -> int:
    """The sweep's `main(["--check", *argv])`, from this file's directory loaded on its own."""
    here = Path(__file__).resolve().parent
    spec = importlib.util.spec_from_file_location(PRIVATE_NAME, here / "__init__.py",
                                                  submodule_search_locations=[str(here)])
    assert spec is not None and spec.loader is not None
    package = importlib.util.module_from_spec(spec)
    sys.modules[PRIVATE_NAME] = package
    spec.loader.exec_module(package)
    return package.main(["--check", *argv])


if __name__ == "__main__":
    sys.exit(run(sys.argv[1:]))

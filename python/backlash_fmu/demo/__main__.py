"""`python -m backlash_fmu.demo [--out DIR] [--short]`: the design answers, the paper's experiments
and the web line, in order (see the package's docstring)."""

from __future__ import annotations

import os
import sys

# Tiny matrices by the thousand: BLAS threads only add synchronisation (tests/python/conftest.py).
for _var in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

from . import main  # noqa: E402

sys.exit(main())

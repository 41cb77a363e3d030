"""The `backlash` command installed with the package:

    backlash design ...     the design study (the design library's command line: the same text,
                            JSON, errors and exit statuses as the workspace's `backlash` binary)
    backlash sweep ...      a tolerance sweep (`python -m backlash_fmu.sweep`)
    backlash demo ...       the paper's experiments (`python -m backlash_fmu.demo`)
"""

from __future__ import annotations

import sys

# The commands this package adds to the design library's.
COMMANDS = """  sweep     tolerance sweep of many drives on Dask (see `backlash sweep --help`)
  demo      the paper's closed-loop experiments and the web line (see `backlash demo --help`)
"""


def main(argv: list[str] | None = None) -> int:
    args = list(sys.argv[1:] if argv is None else argv)
    if args and args[0] == "sweep":
        from .sweep import main as sweep

        return sweep(args[1:])
    if args and args[0] == "demo":
        from .demo import main as demo

        return demo(args[1:])
    from . import _native

    status, out, err = _native.command(args)
    if status == 0 and args and args[0] in ("help", "--help", "-h"):
        # The design library's usage lists its own commands; this command has two more.
        head, sep, tail = out.partition("  help ")
        out = head + COMMANDS + sep + tail
    sys.stdout.write(out)
    sys.stderr.write(err)
    return status


if __name__ == "__main__":
    sys.exit(main())

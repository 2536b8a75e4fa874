"""``python -m drillcosim.build`` (``make fmus``): every piece of C the project builds, ahead of
the first run -- the plant FMUs (:mod:`drillcosim.fmus.build`), the master's C
(:mod:`drillcosim.cosim.loop.native`) and the blocks' kernels (:mod:`drillcosim.controllers.kernels`).
Each is otherwise built on first use; ``--force`` rebuilds what is up to date."""
from __future__ import annotations

import sys

from drillcosim.controllers.kernels import build_all as build_kernels
from drillcosim.cosim.loop.native import build_all as build_native
from drillcosim.fmus.build import main as build_fmus


def main(argv=None) -> int:
    argv = list(sys.argv[1:] if argv is None else argv)
    rc = build_fmus(argv)
    if rc == 0 and not [a for a in argv if not a.startswith("-")]:     # named FMUs only: just those
        force = "--force" in argv
        build_native(force=force)
        build_kernels(force=force)
    return rc


if __name__ == "__main__":
    sys.exit(main())

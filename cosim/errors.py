"""The master's exception types, kept apart so that every module can raise them
without importing the others."""
from __future__ import annotations

import errno


class CosimError(Exception):
    """Base class of every error raised by the master."""


class ScenarioError(CosimError, ValueError):
    """A scenario (file or Python-built system) is invalid; raised before anything runs.

    The message names the file, the key path (``connections[3].to``) and what was expected.
    """

    def __init__(self, message: str, file: str | None = None, key: str | None = None):
        self.file = file
        self.key = key
        self.detail = message
        prefix = ": ".join(p for p in (file, key) if p)
        super().__init__(f"{prefix}: {message}" if prefix else message)


class AlgebraicLoopError(ScenarioError):
    """A cycle among direct-feed-through blocks: no order can give every block fresh inputs."""


class SimulationError(CosimError, RuntimeError):
    """The run stopped on an error of an FMU or a block.

    ``time`` [s] is the communication point at which it happened, ``instance`` the FMU
    or block instance name, ``fmu_message`` the FMU's own last log message (if any).
    ``result`` is set by the runner to the partial :class:`drillcosim.cosim.loop.recorder.Result`.
    """

    def __init__(self, message: str, time: float | None = None, instance: str | None = None,
                 fmu_message: str | None = None):
        self.time = time
        self.instance = instance
        self.fmu_message = fmu_message
        self.result = None
        parts = [message]
        if time is not None:
            parts.insert(0, f"t = {time:.6g} s")
        if instance is not None:
            parts.insert(1 if time is not None else 0, f"instance '{instance}'")
        if fmu_message:
            parts.append(f"FMU says: {fmu_message}")
        super().__init__(": ".join(parts))


class OutputError(CosimError, OSError):
    """The output folder cannot be created, claimed or written (permissions, full disk)."""


def io_problem(what: str, path, e: OSError) -> OutputError:
    """``cannot write data.csv (/x/data.csv): No space left on device [ENOSPC]``."""
    code = errno.errorcode.get(e.errno, "") if e.errno else ""
    reason = e.strerror or str(e)
    return OutputError(f"cannot {what} {path}: {reason}" + (f" [{code}]" if code else ""))

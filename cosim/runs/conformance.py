"""FMI conformance against the Modelica Reference-FMUs (issue 14).

Builds the Reference-FMUs from their source archive (CMake, FMI 2 and 3; nothing is
downloaded), runs each one through the master -- co-simulation, and Model Exchange
with rk4 and cvode -- and compares every numeric output with ``fmpy.simulate_fmu`` on
the same grid. ``python -m drillcosim.cosim.runs.conformance`` (or ``drillcosim conformance``)
regenerates the table in docs/conformance.md; tests/test_conformance.py asserts it.

Where the archive is found (:func:`search_paths`): ``--reference-fmus PATH``,
``$DRILLCOSIM_REFERENCE_FMUS`` (the .tar.gz or its folder), else ``reference-fmus/`` or
``shared/reference-fmus/`` in or above the checkout or the working directory. Builds are cached
in ``<cache>/drillcosim/reference-fmus/<archive hash>/`` (with the archive's LICENSE.txt;
``<cache>`` is ``$XDG_CACHE_HOME`` or ``~/.cache``), so the build happens once per archive, not
per run, and the other project's sources and build scripts stay out of this checkout.
"""
from __future__ import annotations

import argparse
import hashlib
import math
import os
import shutil
import subprocess
import sys
import tarfile
import time as _time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from drillcosim.cosim.fmi.build_tools import BuildLock

REPO = Path(__file__).resolve().parents[2]     # the checkout (or the installed package)
ARCHIVE_GLOB = "Reference-FMUs-*.tar.gz"
ENV = "DRILLCOSIM_REFERENCE_FMUS"
CACHE = Path(os.environ.get("XDG_CACHE_HOME") or Path.home() / ".cache") / "drillcosim" / "reference-fmus"
DOC = REPO / "docs" / "conformance.md"
BEGIN, END = "<!-- conformance table: begin -->", "<!-- conformance table: end -->"


# -- source and build ---------------------------------------------------------------------
def search_paths(explicit: str | Path | None = None) -> list[Path]:
    """Where the archive is looked for, in order: ``explicit`` (``--reference-fmus``),
    ``$DRILLCOSIM_REFERENCE_FMUS``, then ``reference-fmus/`` and ``shared/reference-fmus/``
    in the checkout (or installed package) folder, the working directory and each of their
    parents -- a shared folder beside a set of checkouts is found from any of them, with no
    machine's path written here."""
    out = [Path(explicit)] if explicit else []
    if os.environ.get(ENV):
        out.append(Path(os.environ[ENV]))
    seen = set()
    for start in (REPO, Path.cwd()):
        for d in (start, *start.parents):
            for c in (d / "reference-fmus", d / "shared" / "reference-fmus"):
                if c not in seen:
                    seen.add(c)
                    out.append(c)
    return out


def find_archive(explicit: str | Path | None = None) -> Path | None:
    """The Reference-FMUs source archive, or None (where: :func:`search_paths`)."""
    for c in search_paths(explicit):
        if c.is_file():
            return c
        hits = sorted(c.glob(ARCHIVE_GLOB)) if c.is_dir() else []
        if hits:
            return hits[-1]
    return None


def why_unavailable(explicit: str | Path | None = None) -> str | None:
    """Why the Reference-FMUs cannot be built here, or None."""
    if explicit and not Path(explicit).exists():
        return f"--reference-fmus {explicit}: no such file or folder (expected {ARCHIVE_GLOB} or its folder)"
    if find_archive(explicit) is None:
        places = search_paths(explicit)
        return (f"Reference-FMUs source archive ({ARCHIVE_GLOB}) not found in {places[0]}, {places[1]}, ... "
                f"({len(places)} places: reference-fmus/ and shared/reference-fmus/ in the checkout, the "
                f"working directory and their parents): pass --reference-fmus PATH or set ${ENV}")
    for tool in ("cmake", "cc"):
        if shutil.which(tool) is None and not (tool == "cc" and shutil.which("gcc")):
            return f"'{tool}' is not on PATH (needed to build the Reference-FMUs)"
    return None


def build(jobs: int = 2, quiet: bool = True, archive: str | Path | None = None) -> dict[tuple[int, str], Path]:
    """Build (or reuse) the Reference-FMUs: ``{(fmi_version, model): fmu path}``;
    ``archive``: the archive or its folder (default: :func:`find_archive`)."""
    found = find_archive(archive)
    if found is None:
        raise FileNotFoundError(why_unavailable(archive))
    archive = found
    digest = hashlib.sha256(archive.read_bytes()).hexdigest()[:12]
    root = CACHE / digest
    with BuildLock(CACHE / f"{digest}.lock"):      # two test processes build it once
        _build_into(root, archive, jobs)
    out = {}
    for v in (2, 3):
        for f in sorted((root / f"fmi{v}" / "fmus").glob("*.fmu")):
            out[(v, f.stem)] = f
    return out


def _build_into(root: Path, archive: Path, jobs: int) -> None:
    """Unpack ``archive`` into ``root``/src and CMake-build FMI 2 and 3 where not built yet."""
    src = root / "src"
    if not (src / "CMakeLists.txt").exists():
        src.mkdir(parents=True, exist_ok=True)
        with tarfile.open(archive) as tf:
            tf.extractall(src)
    shutil.copy(src / "LICENSE.txt", root / "LICENSE.txt")
    procs = []
    for v in (2, 3):
        b = root / f"fmi{v}"
        if not list((b / "fmus").glob("*.fmu")):
            cmd = (f"cmake -S {src} -B {b} -DFMI_VERSION={v} -DCMAKE_BUILD_TYPE=Release "
                   f"-DCMAKE_C_FLAGS=-Wno-error=stringop-truncation && cmake --build {b} -j{jobs}")
            procs.append((v, subprocess.Popen(cmd, shell=True, text=True, stdout=subprocess.PIPE,
                                              stderr=subprocess.STDOUT)))
    for v, p in procs:
        log, _ = p.communicate()
        if p.returncode:
            raise RuntimeError(f"building the FMI {v} Reference-FMUs failed:\n{log[-3000:]}")


# -- the cases -------------------------------------------------------------------------------
@dataclass
class Case:
    model: str
    fmi: int
    interface: str                 # CS | ME
    solver: str | None = None      # rk4 | cvode (ME)
    stop: float | None = None      # [s] default: the FMU's default experiment
    step: float | None = None      # [s] communication step, default: the FMU's, else stop/500
    start: float | None = None
    note: str = ""
    cs_tol: float | None = None    # a model-specific CS tolerance (the note says why)

    @property
    def label(self) -> str:
        return f"{self.model} FMI {self.fmi} {self.interface}{' ' + self.solver if self.solver else ''}"


# Relative tolerance of the largest deviation from fmpy, as a fraction of the output's
# range (+ 1e-12 absolute): CS runs the same FMU code on the same grid, so they agree to
# rounding; ME rk4 at the communication step is a 4th-order method against fmpy's CVODE
# at rel_tol 1e-10 (error ~ (h / T)^4); ME cvode at rel_tol 1e-8.
TOLERANCE = {"CS": 1e-9, "rk4": 2e-3, "cvode": 1e-4}
REFERENCE_RTOL = 1e-10          # fmpy's CVODE for the Model Exchange reference

# Per model: experiment overrides and why.
SETTINGS = {
    "Roberts": dict(stop=40.0, step=0.01, cs_tol=1e-6,
                    note="CS within 1e-6: fmpy accumulates t += h, the master uses t0 + n*h, and the FMU's "
                         "fixed internal Euler sub-steps follow the communication points; "
                         "span 1e-5 .. 40 s (the default 1e8 s needs a stiff variable-step solver; "
                         "rk4 at a fixed step goes non-finite and the run fails, as it must)"),
    "StateSpace": dict(step=0.01),
    "Feedthrough": dict(step=0.01),
    "Resource": dict(step=0.01),
}


@dataclass
class Row:
    case: Case
    status: str                      # pass | fail | unsupported
    detail: str = ""
    worst: float | None = None       # largest relative deviation from fmpy
    outputs: int = 0
    seconds: float = 0.0
    run_status: str = ""
    extra: dict = field(default_factory=dict)


def _experiment(path: Path, case: Case):
    from fmpy import read_model_description
    md = read_model_description(str(path), validate=False)
    de = md.defaultExperiment
    start = case.start if case.start is not None else float(de.startTime or 0.0) if de else 0.0
    stop = case.stop if case.stop is not None else float(de.stopTime) if de and de.stopTime else 1.0
    step = case.step if case.step is not None else float(de.stepSize) if de and de.stepSize else (stop - start) / 500
    return md, start, stop, step


def run_master(path: Path, case: Case, out_dir: Path | None = None):
    """The master's run of one case: ``(Result, RunInfo dict)``."""
    from drillcosim.cosim.loop.algorithm import run
    from drillcosim.cosim.fmi.model_exchange import create_slave
    from drillcosim.cosim.loop.recorder import Recorder
    from drillcosim.cosim.loop.system import System
    _md, start, stop, step = _experiment(path, case)
    system = System(step_size=step, start_time=start)
    opts = {"solver": case.solver} if case.interface == "ME" else {}
    system.add_fmu("fmu", create_slave("fmu", path, interface=case.interface, **opts))
    result = run(system, stop, Recorder(["*"], out_dir=out_dir))
    return result, result.summary


def run_fmpy(path: Path, case: Case):
    from fmpy import simulate_fmu
    _md, start, stop, step = _experiment(path, case)
    kw = dict(start_time=start, stop_time=stop, output_interval=step)
    if case.interface == "CS":
        kw.update(fmi_type="CoSimulation")
    else:
        kw.update(fmi_type="ModelExchange", solver="CVode", relative_tolerance=REFERENCE_RTOL, step_size=step)
    return simulate_fmu(str(path), **kw)


def compare(result, ref) -> tuple[float, int, str]:
    """Largest deviation of the master's numeric outputs from fmpy's, relative to each
    output's range, at the master's time points away from fmpy's event instants."""
    t_ref = np.asarray(ref["time"], dtype=float)
    events = t_ref[1:][np.diff(t_ref) <= 0]          # fmpy records an event as two rows
    t = result.time
    keep = np.ones(len(t), bool)
    step = np.median(np.diff(t)) if len(t) > 1 else 0.0
    for te in events:
        keep &= np.abs(t - te) > 1.5 * step
    worst, worst_name, n = 0.0, "", 0
    for name in result.signals:
        var = name.split(".", 1)[1]
        if var not in ref.dtype.names and var.split("[")[0] not in ref.dtype.names:
            continue
        col = result[name]
        if col.dtype == object:
            continue
        y_ref = np.asarray(ref[var.split("[")[0]], dtype=float)
        if y_ref.ndim > 1:                            # FMI 3 arrays: (rows, n)
            idx = int(var[var.index("[") + 1:-1].split(",")[0]) - 1
            y_ref = y_ref[:, idx]
        # fmpy's rows at an event: take the value after it (the later row at that time)
        tt, first = np.unique(t_ref[::-1], return_index=True)
        yy = y_ref[::-1][first]
        y = np.interp(t[keep], tt, yy)
        dev = np.abs(col[keep].astype(float) - y)
        scale = max(np.ptp(yy), np.max(np.abs(yy)), 1e-12) if len(yy) else 1.0
        rel = float(np.max(dev) / scale) if dev.size else 0.0
        n += 1
        if rel > worst:
            worst, worst_name = rel, name
    return worst, n, worst_name


def run_case(path: Path | None, case: Case) -> Row:
    from drillcosim.cosim.errors import CosimError
    from drillcosim.cosim.fmi.model_exchange import SE_UNSUPPORTED, fmu_kinds
    t0 = _time.perf_counter()
    if path is None:
        return Row(case, "unsupported", "not built for this FMI version")
    kinds = fmu_kinds(path)
    if "CS" not in kinds and "ME" not in kinds:
        return Row(case, "unsupported", SE_UNSUPPORTED)
    try:
        result, info = run_master(path, case)
    except CosimError as e:
        if case.model == "Roberts" and case.solver == "rk4" and "non-finite" in str(e):
            return Row(case, "pass", "fails honestly: " + str(e).split(":")[0] + " (non-finite state)",
                       seconds=_time.perf_counter() - t0, run_status="failed")
        return Row(case, "fail", f"{type(e).__name__}: {e}", seconds=_time.perf_counter() - t0)
    ref = run_fmpy(path, case)
    worst, n, name = compare(result, ref)
    tol = (case.cs_tol if case.interface == "CS" and case.cs_tol else None) or TOLERANCE[case.solver or "CS"]
    ok = worst <= tol and info.get("status") in ("completed", "stopped")
    detail = f"max deviation {worst:.1e} ({name or '-'}) <= {tol:g}" if ok else \
        f"max deviation {worst:.1e} ({name}) > {tol:g} or status {info.get('status')}"
    return Row(case, "pass" if ok else "fail", detail, worst, n, _time.perf_counter() - t0,
               info.get("status", ""), {"time_reached": info.get("time_reached"),
                                        "stop_reason": info.get("stop_reason")})


def run_all(built: dict) -> list[Row]:
    rows = []
    models = sorted({m for _v, m in built})
    for model in models:
        for v in (2, 3):
            path = built.get((v, model))
            s = SETTINGS.get(model, {})
            if path is None:
                continue
            from drillcosim.cosim.fmi.model_exchange import fmu_kinds
            if not {"CS", "ME"} & set(fmu_kinds(path)):       # Scheduled Execution only: one row
                rows.append(run_case(path, Case(model, v, "SE", None, **s)))
                continue
            for iface, solver in (("CS", None), ("ME", "rk4"), ("ME", "cvode")):
                rows.append(run_case(path, Case(model, v, iface, solver, **s)))
    return rows


def table(rows: list[Row]) -> str:
    lines = ["| FMU | FMI | interface | result | run | outputs compared | max deviation from fmpy | note |",
             "|---|---|---|---|---|---|---|---|"]
    for r in rows:
        c = r.case
        dev = f"{r.worst:.1e}" if r.worst is not None else "-"
        note = c.note if r.status != "unsupported" else r.detail
        if r.status == "fail":
            note = r.detail
        elif r.run_status == "failed":
            note = r.detail + ("; " + c.note if c.note else "")
        elif r.run_status == "stopped":
            note = (f"stopped: {r.extra.get('stop_reason')}" + ("; " + c.note if c.note else ""))
        iface = c.interface + (f" {c.solver}" if c.solver else "")
        lines.append(f"| {c.model} | {c.fmi} | {iface} | {r.status} | {r.run_status or '-'} | "
                     f"{r.outputs} | {dev} | {note} |")
    return "\n".join(lines)


def write_doc(rows: list[Row], doc: Path = DOC) -> None:
    text = doc.read_text()
    a, b = text.index(BEGIN) + len(BEGIN), text.index(END)
    doc.write_text(text[:a] + "\n" + table(rows) + "\n" + text[b:])


def main(argv=None) -> int:
    p = argparse.ArgumentParser(prog="python -m drillcosim.cosim.runs.conformance",
                                description="Run the Reference-FMUs through the master, compare with fmpy, "
                                            "and rewrite the table in docs/conformance.md")
    p.add_argument("--no-write", action="store_true", help="print the table only")
    p.add_argument("--reference-fmus", metavar="PATH", help=f"the {ARCHIVE_GLOB} archive or its folder "
                   f"(default: ${ENV}, else reference-fmus/ or shared/reference-fmus/ in or above the checkout "
                   "or the working directory)")
    args = p.parse_args(argv)
    why = why_unavailable(args.reference_fmus)
    if why:
        print(f"conformance: {why}", file=sys.stderr)
        return 1
    rows = run_all(build(archive=args.reference_fmus))
    print(table(rows))
    if not args.no_write:
        write_doc(rows)
        print(f"written: {DOC}")
    return 0 if all(r.status != "fail" for r in rows) else 1


if __name__ == "__main__":
    sys.exit(main())

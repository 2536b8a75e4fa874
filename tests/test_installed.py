"""drillcosim as a user gets it: ``pip install .`` into a fresh virtual environment, then
used from another folder, with nothing of the checkout on sys.path.

The fresh environment finds the dependencies (numpy, fmpy, ...) through a ``.pth`` line
naming the test environment's site-packages -- a plain path, so the checkout's editable
install there stays inactive -- which keeps the test off the network.
"""
from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
import sysconfig
import venv
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]


def _run(cmd, cwd, timeout=600, **kw):
    env = {k: v for k, v in os.environ.items() if k not in ("PYTHONPATH", "VIRTUAL_ENV")}
    r = subprocess.run(cmd, cwd=cwd, capture_output=True, text=True, timeout=timeout, env=env, **kw)
    assert r.returncode == 0, f"{' '.join(map(str, cmd))} -> {r.returncode}\n{r.stdout[-3000:]}\n{r.stderr[-3000:]}"
    return r.stdout


@pytest.fixture(scope="module")
def installed(tmp_path_factory):
    """A fresh venv with the package installed from a wheel built from this checkout."""
    tmp = tmp_path_factory.mktemp("installed")
    # from a copy: setuptools builds in the source tree (build/lib), never removes a stale file
    # there, and other tests run beside this one
    src = tmp / "src"
    shutil.copytree(ROOT, src, ignore=shutil.ignore_patterns(".venv", ".git", "results", "build", "dist",
                                                             "__pycache__", "*.egg-info", ".pytest_cache"))
    wheels = tmp / "wheels"
    _run([sys.executable, "-m", "pip", "wheel", "--no-deps", "--no-build-isolation", "-q", "-w", str(wheels),
          str(src)], cwd=tmp)
    env_dir = tmp / "venv"
    venv.EnvBuilder(with_pip=False).create(env_dir)      # this pip installs into it (--python): no ensurepip
    py = env_dir / "bin" / "python"
    site = Path(_run([str(py), "-c", "import sysconfig; print(sysconfig.get_paths()['purelib'])"], cwd=tmp).strip())
    (site / "zz_test_dependencies.pth").write_text(sysconfig.get_paths()["purelib"] + "\n")
    wheel = next(wheels.glob("drillcosim-*.whl"))
    _run([sys.executable, "-m", "pip", "--python", str(py), "install", "--no-deps", "-q", str(wheel)], cwd=tmp)
    work = tmp / "elsewhere"
    work.mkdir()
    return env_dir, work


def test_one_namespace_imports_from_the_install(installed):
    env_dir, work = installed
    out = _run([str(env_dir / "bin" / "python"), "-c",
                "import json, drillcosim, drillcosim.cosim, drillcosim.controllers, drillcosim.analysis; "
                "import importlib.util as u; print(json.dumps([drillcosim.__file__, drillcosim.__version__, "
                "[m for m in ('cosim', 'controllers', 'analysis', 'fmus', 'drilling') if u.find_spec(m)]]))"],
               cwd=work)
    file, version, top_level = json.loads(out.strip().splitlines()[-1])
    assert str(env_dir) in file and str(ROOT) not in file
    assert version != "0+unknown"
    assert top_level == []          # no generic top-level names in site-packages


def test_list_shows_every_shipped_scenario(installed):
    from drillcosim.cosim.scenario.loader import scenario_files
    env_dir, work = installed
    out = _run([str(env_dir / "bin" / "drillcosim"), "list"], cwd=work)
    listed = [line.split()[0] for line in out.splitlines() if line.strip()]
    shipped = [name for name, _ in scenario_files(ROOT / "scenarios")]
    assert len(shipped) >= 30
    assert listed == shipped


def test_run_by_name_completes_from_another_folder(installed):
    env_dir, work = installed
    _run([str(env_dir / "bin" / "drillcosim"), "run", "keio_fig7_aluminium_force_control", "--out", "fig7",
          "--quiet"], cwd=work)
    summary = json.loads((work / "fig7" / "summary.json").read_text())
    assert summary["status"] == "completed"
    assert summary["scores_passed"] is True
    assert Path(summary["file"]).resolve().is_relative_to(env_dir.resolve())   # the shipped file

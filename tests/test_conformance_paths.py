"""Where `drillcosim conformance` finds the Reference-FMUs archive: an option, the
environment, or a folder in or above the checkout -- no machine's path in the code."""
from __future__ import annotations

from pathlib import Path

import pytest

import drillcosim.cosim.runs.conformance as conf
from drillcosim.cli import main


@pytest.fixture
def elsewhere(tmp_path, monkeypatch):
    """A checkout at tmp/work/wt/x with nothing set: the search starts from there."""
    checkout = tmp_path / "work" / "wt" / "x"
    checkout.mkdir(parents=True)
    monkeypatch.setattr(conf, "REPO", checkout)
    monkeypatch.delenv(conf.ENV, raising=False)
    monkeypatch.chdir(checkout)
    return tmp_path


def _archive(folder: Path) -> Path:
    folder.mkdir(parents=True, exist_ok=True)
    p = folder / "Reference-FMUs-0.0.1.tar.gz"
    p.write_bytes(b"")
    return p


def test_no_hard_coded_machine_path():
    assert "/work/" not in Path(conf.__file__).read_text()


def test_a_shared_folder_above_the_checkout_is_found(elsewhere):
    want = _archive(elsewhere / "work" / "shared" / "reference-fmus")
    assert conf.find_archive() == want


def test_the_option_wins_over_the_environment(elsewhere, monkeypatch):
    monkeypatch.setenv(conf.ENV, str(_archive(elsewhere / "env")))
    mine = _archive(elsewhere / "mine")
    assert conf.find_archive(mine.parent) == mine
    assert conf.find_archive() == elsewhere / "env" / mine.name


def test_absent_archive_is_a_clear_error(elsewhere, capsys):
    assert conf.find_archive() is None
    assert main(["conformance", "--no-write"]) == 1
    err = capsys.readouterr().err
    assert "Reference-FMUs source archive (Reference-FMUs-*.tar.gz) not found in" in err
    assert "pass --reference-fmus PATH or set $DRILLCOSIM_REFERENCE_FMUS" in err
    assert main(["conformance", "--reference-fmus", str(elsewhere / "nope")]) == 1
    assert "nope: no such file or folder" in capsys.readouterr().err

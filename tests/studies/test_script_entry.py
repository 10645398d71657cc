"""Every study script runs the three documented ways: as a module from the repository root
(``python -m studies.X.stage``), as a file from any folder (``python studies/X/stage.py``, where
the script's own folder would shadow the toolkit's packages ``pre``, ``compute``, ``post``), and
through its console command of pyproject.toml.

The console commands exist only once the toolkit is installed; the shared test environment is
installed from another checkout, so they are checked here through what pip's wrapper does
(import the ``module:function`` of [project.scripts] and ``sys.exit(function())`` with the
command's arguments in ``sys.argv``), with this checkout on PYTHONPATH in place of the
installation, and run for real only when the command is on PATH."""

import os
import shutil
import subprocess
import sys
import tomllib
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
SCRIPTS = sorted(p for p in (ROOT / "studies").glob("*/*.py") if p.name != "__init__.py")
PROJECT = tomllib.loads((ROOT / "pyproject.toml").read_text())
COMMANDS = PROJECT["project"]["scripts"]


def module_of(script: Path) -> str:
    return ".".join(script.relative_to(ROOT).with_suffix("").parts)


def env_without_pythonpath() -> dict:
    """The environment of a user who has not set PYTHONPATH (the test runner may have)."""
    return {k: v for k, v in os.environ.items() if k != "PYTHONPATH"}


def help_ran(result: subprocess.CompletedProcess) -> bool:
    return result.returncode == 0 and result.stdout.startswith("usage:")


def test_every_study_script_is_found():
    assert {p.stem for p in SCRIPTS} >= {"pre", "compute", "post"}
    for study in ("mixture_compaction", "rigid_jamming", "single_particle"):
        assert {"pre", "compute", "post"} <= {p.stem for p in SCRIPTS if p.parent.name == study}


@pytest.mark.parametrize("script", SCRIPTS, ids=module_of)
def test_as_a_module_from_the_repository_root(script):
    r = subprocess.run([sys.executable, "-m", module_of(script), "--help"], cwd=ROOT, capture_output=True,
                       text=True, timeout=120)
    assert help_ran(r), r.stderr


@pytest.mark.parametrize("script", SCRIPTS, ids=module_of)
def test_as_a_file_from_another_folder(script, tmp_path):
    r = subprocess.run([sys.executable, str(script), "--help"], cwd=tmp_path, env=env_without_pythonpath(),
                       capture_output=True, text=True, timeout=120)
    assert help_ran(r), r.stderr


def test_a_stage_run_as_a_file_imports_the_toolkit_not_its_neighbours(tmp_path):
    """studies/single_particle/pre.py imports ``pre.single_particle`` inside main(): with its own
    folder first on sys.path, ``pre`` would be the script itself."""
    script = ROOT / "studies" / "single_particle" / "pre.py"
    r = subprocess.run([sys.executable, str(script), "--workdir", "w", "--elements", "30"], cwd=tmp_path,
                       env=env_without_pythonpath(), capture_output=True, text=True, timeout=300)
    assert r.returncode == 0, r.stderr
    assert (tmp_path / "w" / "scene" / "scene.toml").is_file()


def test_every_script_has_a_console_command():
    targets = {target.split(":")[0] for target in COMMANDS.values()}
    assert {module_of(p) for p in SCRIPTS} <= targets
    assert {"compute.__main__", "post.__main__"} <= targets


def test_the_packages_found_for_installation_hold_every_command():
    from setuptools import find_packages

    found = set(find_packages(str(ROOT), include=PROJECT["tool"]["setuptools"]["packages"]["find"]["include"]))
    for target in COMMANDS.values():
        assert target.split(":")[0].rpartition(".")[0] in found, target


@pytest.mark.parametrize("command", sorted(COMMANDS))
def test_console_command(command, tmp_path):
    """What pip's wrapper of the command does, from another folder; the command itself when on PATH."""
    module, function = COMMANDS[command].split(":")
    wrapper = f"import sys; from {module} import {function}; sys.argv = [{command!r}, '--help']; sys.exit({function}())"
    env = {**env_without_pythonpath(), "PYTHONPATH": str(ROOT)}
    r = subprocess.run([sys.executable, "-c", wrapper], cwd=tmp_path, env=env, capture_output=True, text=True,
                       timeout=120)
    assert help_ran(r), r.stderr
    installed = shutil.which(command)
    if installed is not None:
        r = subprocess.run([installed, "--help"], cwd=tmp_path, capture_output=True, text=True, timeout=120)
        assert help_ran(r), r.stderr

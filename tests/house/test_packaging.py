"""The wheel holds everything the package reads at run time, and runs from any folder.

The other tests import the source tree; these build the wheel a user installs and run
the command line from it, in a folder that is not the checkout.
"""

import shutil
import subprocess
import sys
import zipfile
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
PACKAGE = ROOT / "packetloss_cvx"


@pytest.fixture(scope="module")
def wheel(tmp_path_factory) -> Path:
    out = tmp_path_factory.mktemp("wheel")
    # a clean copy: a stale *.egg-info or build/ in the checkout would hide a missing package-data entry
    src = out / "src"
    shutil.copytree(ROOT, src, ignore=shutil.ignore_patterns(
        "*.egg-info", "build", "dist", "__pycache__", ".git", ".hypothesis", ".pytest_cache", ".benchmarks"))
    proc = subprocess.run(
        [sys.executable, "-m", "pip", "wheel", "--no-deps", "-q", "-w", str(out), str(src)],
        capture_output=True, text=True, check=False,
    )
    assert proc.returncode == 0, proc.stderr
    (path,) = out.glob("packetloss_cvx-*.whl")
    return path


def test_wheel_holds_every_module_and_data_file(wheel):
    names = set(zipfile.ZipFile(wheel).namelist())
    wanted = {p.relative_to(ROOT).as_posix() for p in PACKAGE.rglob("*")
              if p.suffix in (".py", ".toml") and "__pycache__" not in p.parts}
    assert "packetloss_cvx/model/examples/pendulum.toml" in wanted
    assert wanted <= names, sorted(wanted - names)


def test_cli_runs_from_the_unpacked_wheel_in_another_folder(wheel, tmp_path):
    site = tmp_path / "site"
    zipfile.ZipFile(wheel).extractall(site)
    work = tmp_path / "work"
    work.mkdir()
    env = {"PYTHONPATH": str(site), "PATH": "/usr/bin:/bin"}
    where = subprocess.run([sys.executable, "-c", "import packetloss_cvx; print(packetloss_cvx.__file__)"],
                           cwd=work, env=env, capture_output=True, text=True, check=True).stdout
    assert where.startswith(str(site)), where   # the wheel's copy, not the checkout
    proc = subprocess.run(
        [sys.executable, "-m", "packetloss_cvx", "audit", "--random", "2", "--seed", "1", "--claim", "theorem-3",
         "--json"], cwd=work, env=env, capture_output=True, text=True, check=False,
    )
    assert proc.returncode == 0, proc.stderr
    assert '"id": "theorem-3"' in proc.stdout
    solve = subprocess.run([sys.executable, "-m", "packetloss_cvx", "solve", "pendulum", "--no-qp"], cwd=work,
                           env=env, capture_output=True, text=True, check=False)
    assert solve.returncode == 0, solve.stderr

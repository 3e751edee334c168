"""``colcon build`` installs the node executables where ``ros2 run flexmotion_ros planner`` looks.

``ros2 run PKG EXE`` runs ``<prefix>/lib/PKG/EXE`` (setup.cfg sends the
console scripts there).  The package is copied into a temporary workspace so
the build never writes into the repository.
"""

from __future__ import annotations

import os
import shutil
import stat
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
COLCON = Path(sys.executable).with_name("colcon")
IGNORE = shutil.ignore_patterns(
    ".git", ".venv", "build", "install", "log", "__pycache__", "*.egg-info", ".pytest_cache", ".hypothesis", "*.png"
)


@pytest.fixture(scope="module")
def install(tmp_path_factory) -> Path:
    if not COLCON.exists():
        pytest.fail(f"colcon not found next to {sys.executable} (pip install colcon-common-extensions)")
    ws = tmp_path_factory.mktemp("colcon_ws")
    shutil.copytree(ROOT, ws / "src" / "flexmotion_ros", ignore=IGNORE)
    env = {k: v for k, v in os.environ.items() if not k.startswith(("COLCON", "AMENT_PREFIX_PATH"))}
    proc = subprocess.run(
        [str(COLCON), "build", "--base-paths", "src", "--event-handlers", "console_direct-"],
        cwd=ws,
        env=env,
        capture_output=True,
        text=True,
        timeout=55,
        check=False,
    )
    assert proc.returncode == 0, proc.stdout[-3000:] + proc.stderr[-3000:]
    return ws / "install" / "flexmotion_ros"


@pytest.mark.parametrize("exe", ["planner", "plant", "flexmotion"])
def test_executables_installed_where_ros2_run_looks(install, exe):
    path = install / "lib" / "flexmotion_ros" / exe
    assert path.is_file(), sorted(p.name for p in (install / "lib" / "flexmotion_ros").iterdir())
    assert path.stat().st_mode & stat.S_IXUSR


def test_package_index_and_configs_installed(install):
    share = install / "share"
    assert (share / "ament_index" / "resource_index" / "packages" / "flexmotion_ros").is_file()
    assert (share / "flexmotion_ros" / "package.xml").is_file()
    assert {p.name for p in (share / "flexmotion_ros" / "config").glob("*.yaml")} >= {"wie_bernstein.yaml"}


@pytest.mark.parametrize("exe", ["planner", "plant"])
def test_installed_nodes_run_and_refuse_a_bad_parameter_file(install, tmp_path, exe):
    """The installed scripts start the real nodes: a bad file exits with status 2 and the reason."""
    bad = tmp_path / "bad.yaml"
    bad.write_text(
        "/**:\n  ros__parameters:\n    model:\n      b0: 0.5\n      omega: [1.0]\n      zeta: [1.5]\n      b: [1.0]\n"
    )
    env = dict(os.environ, ROS_AUTOMATIC_DISCOVERY_RANGE="LOCALHOST")
    proc = subprocess.run(
        [str(install / "lib" / "flexmotion_ros" / exe), "--ros-args", "--params-file", str(bad)],
        capture_output=True,
        text=True,
        timeout=30,
        env=env,
        check=False,
    )
    assert proc.returncode == 2, proc.stderr
    assert f"flexmotion_{exe}: error: model.zeta[0]: must be in [0, 1)" in proc.stderr

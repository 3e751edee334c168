"""``colcon build`` installs the node executables where ``ros2 run flexmotion_ros planner`` looks.

``ros2 run PKG EXE`` runs ``<prefix>/lib/PKG/EXE`` (setup.cfg sends the
console scripts there).  The package is copied into a temporary workspace so
the build never writes into the repository.  The installed package, run from
outside any source checkout with the environment ``source install/setup.bash``
gives, finds its shipped parameter files in ``share/flexmotion_ros/config``.
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


def sourced_environment(install: Path) -> dict[str, str]:
    """What ``source install/setup.bash`` sets for this package: AMENT_PREFIX_PATH and PYTHONPATH."""
    (site,) = install.glob("lib/python3*/site-packages")
    env = {k: v for k, v in os.environ.items() if not k.startswith(("COLCON", "AMENT_PREFIX_PATH", "PYTHONPATH"))}
    env.update(AMENT_PREFIX_PATH=str(install), PYTHONPATH=str(site), ROS_AUTOMATIC_DISCOVERY_RANGE="LOCALHOST")
    return env


WHERE = (
    "import flexmotion_ros; from flexmotion_ros.cli.demo_cmd import default_config; "
    "print(flexmotion_ros.__file__); print(default_config())"
)


@pytest.mark.parametrize("sourced", [True, False], ids=["sourced", "not_sourced"])
def test_installed_package_finds_its_config_in_the_install_tree(install, tmp_path, sourced):
    """Outside the checkout, the installed package's default config is ``<install>/share/flexmotion_ros/config``.

    Not sourced (no AMENT_PREFIX_PATH, only the install on PYTHONPATH), the
    prefix the package is installed under is searched.
    """
    env = sourced_environment(install)
    if not sourced:
        del env["AMENT_PREFIX_PATH"]
    proc = subprocess.run(
        [sys.executable, "-c", WHERE], cwd=tmp_path, env=env, capture_output=True, text=True, timeout=60, check=False
    )
    assert proc.returncode == 0, proc.stderr
    module, config = proc.stdout.split()
    assert Path(module).is_relative_to(install), module  # the installed package, not the source tree
    assert Path(config) == install / "share" / "flexmotion_ros" / "config" / "wie_bernstein.yaml"


def test_installed_demo_runs_with_its_default_config(install, tmp_path):
    """``<install>/lib/flexmotion_ros/flexmotion demo`` without ``--config``: a real move over DDS from the install."""
    proc = subprocess.run(
        [str(install / "lib" / "flexmotion_ros" / "flexmotion"), "demo", "--goal", "1.0", "--plot", ""],
        cwd=tmp_path,
        env=sourced_environment(install),
        capture_output=True,
        text=True,
        timeout=150,
        check=False,
    )
    assert proc.returncode == 0, proc.stdout[-2000:] + proc.stderr[-3000:]
    config = install / "share" / "flexmotion_ros" / "config" / "wie_bernstein.yaml"
    assert f"move                 0 -> 1  ({config})" in proc.stdout
    assert "measured arrival     4.218000 s" in proc.stdout

"""``flexmotion_ros.cli.shipped``: shipped files found in install prefixes, then the source checkout.

Every lookup here runs on a temporary install tree (``<prefix>/share/flexmotion_ros/...``,
``<prefix>/lib/flexmotion_ros/...``), with the environment and ``sys.prefix`` passed in.
"""

from __future__ import annotations

import stat
from pathlib import Path

import pytest

from flexmotion_ros.cli import shipped
from flexmotion_ros.cli.demo_cmd import default_config
from flexmotion_ros.cli.main import main

ROOT = Path(__file__).resolve().parents[2]
CONFIG = "config/wie_bernstein.yaml"


def make_prefix(root: Path, *files: str) -> Path:
    """An install prefix holding ``share/flexmotion_ros/<file>`` for each file."""
    for f in files:
        path = root / "share" / "flexmotion_ros" / f
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text(f"# {root.name}\n")
    return root


def make_executable(path: Path) -> Path:
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text("#!/bin/sh\n")
    path.chmod(path.stat().st_mode | stat.S_IXUSR)
    return path


def test_ament_prefix_path_is_searched_in_order(tmp_path):
    empty = make_prefix(tmp_path / "empty")  # no such file: skipped
    first = make_prefix(tmp_path / "first", CONFIG)
    second = make_prefix(tmp_path / "second", CONFIG)
    env = {"AMENT_PREFIX_PATH": f"{empty}:{first}:{second}"}
    found = shipped.find_shipped(CONFIG, env, str(tmp_path / "no_python_prefix"))
    assert found == first / "share" / "flexmotion_ros" / CONFIG


def test_sys_prefix_after_ament_prefix_path(tmp_path):
    """A pip install: data_files under sys.prefix; AMENT_PREFIX_PATH still comes first."""
    pip = make_prefix(tmp_path / "venv", CONFIG)
    assert shipped.find_shipped(CONFIG, {}, str(pip)) == pip / "share" / "flexmotion_ros" / CONFIG
    ros = make_prefix(tmp_path / "ros", CONFIG)
    assert shipped.find_shipped(CONFIG, {"AMENT_PREFIX_PATH": str(ros)}, str(pip)).is_relative_to(ros)


def test_source_checkout_is_the_last_resort(tmp_path, monkeypatch):
    assert shipped.SOURCE_ROOT == ROOT  # this test runs from the checkout
    assert shipped.find_shipped(CONFIG, {}, str(tmp_path)) == ROOT / CONFIG
    assert shipped.share_directories({}, str(tmp_path))[-1] == ROOT
    monkeypatch.setattr(shipped, "SOURCE_ROOT", None)
    assert shipped.find_shipped(CONFIG, {}, str(tmp_path)) is None


def test_every_shipped_config_is_found_in_the_checkout(tmp_path):
    for path in sorted((ROOT / "config").glob("*.yaml")):
        assert shipped.find_shipped(f"config/{path.name}", {}, str(tmp_path)) == path


def test_demo_default_config_uses_the_lookup(tmp_path, monkeypatch):
    prefix = make_prefix(tmp_path / "install", CONFIG)
    monkeypatch.setenv("AMENT_PREFIX_PATH", str(prefix))
    assert default_config() == str(prefix / "share" / "flexmotion_ros" / CONFIG)


def test_demo_without_a_config_anywhere_is_one_line(tmp_path, monkeypatch, capsys):
    """Nothing found: exit 2, one line naming --config and where it looked; nothing on stdout, no node started."""
    monkeypatch.setattr(shipped, "SOURCE_ROOT", None)
    monkeypatch.setattr(shipped.sys, "prefix", str(tmp_path / "py"))
    monkeypatch.setenv("AMENT_PREFIX_PATH", str(tmp_path / "ros"))
    assert main(["demo", "--plot", ""]) == 2
    out, err = capsys.readouterr()
    assert out == ""
    assert err.count("\n") == 1 and err.startswith("flexmotion: error: config: no default parameter file found")
    assert str(tmp_path / "ros" / "share" / "flexmotion_ros" / CONFIG) in err and "give --config FILE" in err


def test_find_executable_prefers_the_install_lib_directory(tmp_path):
    """colcon puts executables in <prefix>/lib/flexmotion_ros (ros2 run looks there), pip in <sys.prefix>/bin."""
    ros = make_executable(tmp_path / "ros" / "lib" / "flexmotion_ros" / "flexmotion")
    pip = make_executable(tmp_path / "venv" / "bin" / "flexmotion")
    env = {"AMENT_PREFIX_PATH": str(tmp_path / "ros"), "PATH": ""}
    assert shipped.find_executable("flexmotion", env, str(tmp_path / "venv")) == ros
    assert shipped.find_executable("flexmotion", {"PATH": ""}, str(tmp_path / "venv")) == pip


def test_find_executable_on_path_and_not_found(tmp_path):
    bindir = tmp_path / "bin"
    exe = make_executable(bindir / "flexmotion_shipped_test_tool")
    found = shipped.find_executable("flexmotion_shipped_test_tool", {"PATH": str(bindir)}, str(tmp_path / "venv"))
    assert found == exe
    plain = bindir / "not_executable"
    plain.write_text("")
    assert shipped.find_executable("not_executable", {"PATH": str(bindir)}, str(tmp_path)) is None


@pytest.mark.parametrize("name", ["flexmotion", "planner", "plant"])
def test_this_installation_has_its_executables(name):
    """In this pip venv or colcon workspace, every console script is found."""
    assert shipped.find_executable(name) is not None

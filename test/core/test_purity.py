"""The numerical core never imports rclpy (nor any ROS package)."""

import ast
import json
import subprocess
import sys
from pathlib import Path

import pytest

CORE = Path(__file__).resolve().parents[2] / "flexmotion_ros" / "core"
ROS_PACKAGES = (
    "rclpy",
    "rcl_interfaces",
    "rosidl_runtime_py",
    "builtin_interfaces",
    "std_msgs",
    "std_srvs",
    "sensor_msgs",
    "trajectory_msgs",
    "nav_msgs",
    "diagnostic_msgs",
    "geometry_msgs",
    "launch",
    "launch_ros",
    "ament_index_python",
)


def is_ros(name: str) -> bool:
    return name.split(".")[0] in ROS_PACKAGES


def ros_imports(source: str) -> list[str]:
    """Names of ROS modules a source imports: ``import x``, ``from x import``, and
    ``importlib.import_module("x")`` / ``__import__("x")`` with a literal name.
    Relative imports of ``flexmotion_ros.nodes`` (the ROS adapters) count too."""
    found = []
    for node in ast.walk(ast.parse(source)):
        if isinstance(node, ast.Import):
            found += [a.name for a in node.names if is_ros(a.name) or ".nodes" in a.name]
        elif isinstance(node, ast.ImportFrom):
            mod = node.module or ""
            if (
                (node.level == 0 and is_ros(mod))
                or mod.startswith("nodes")
                or ".nodes" in mod
                or "flexmotion_ros.nodes" in mod
            ):
                found.append("." * node.level + mod)
            elif node.level >= 2 and any(a.name == "nodes" for a in node.names):
                found.append("." * node.level + "nodes")
        elif isinstance(node, ast.Call):
            fn = node.func
            name = fn.attr if isinstance(fn, ast.Attribute) else getattr(fn, "id", "")
            if name in ("import_module", "__import__") and node.args:
                arg = node.args[0]
                if isinstance(arg, ast.Constant) and isinstance(arg.value, str) and is_ros(arg.value):
                    found.append(arg.value)
    return found


def core_sources() -> list[Path]:
    files = sorted(CORE.rglob("*.py"))
    assert len(files) >= 10, "core sources not found"
    return files


@pytest.mark.parametrize("path", core_sources(), ids=lambda p: p.name)
def test_core_file_never_imports_ros(path):
    assert ros_imports(path.read_text()) == [], f"{path.name} imports ROS"


@pytest.mark.parametrize(
    "snippet",
    [
        "import rclpy",
        "import rclpy.node as n",
        "from rclpy.node import Node",
        "from std_msgs.msg import Float64",
        "def f():\n    import sensor_msgs.msg\n",
        "import importlib\nimportlib.import_module('rclpy')",
        "__import__('trajectory_msgs.msg')",
        "from ..nodes import planner_node",
        "from ..nodes.planner_node import main",
        "from flexmotion_ros.nodes import planner_node",
    ],
)
def test_the_scanner_catches_ros_imports(snippet):
    assert ros_imports(snippet), snippet


@pytest.mark.parametrize(
    "snippet",
    [
        '"""Never imports rclpy."""',
        "import numpy as np",
        "from .model import ModalModel",
        "x = 'rclpy'",
    ],
)
def test_the_scanner_ignores_mentions(snippet):
    assert ros_imports(snippet) == []


def test_importing_the_core_does_not_import_ros():
    code = (
        "import importlib, json, pkgutil, sys\n"
        "import flexmotion_ros.core as core\n"
        "names = [m.name for m in pkgutil.walk_packages(core.__path__, 'flexmotion_ros.core.')]\n"
        "for n in names:\n"
        "    importlib.import_module(n)\n"
        "import flexmotion_ros.core.methods\n"
        "print(json.dumps({'modules': names, 'loaded': sorted(sys.modules)}))\n"
    )
    res = subprocess.run(
        [sys.executable, "-c", code],
        capture_output=True,
        text=True,
        timeout=300,
        check=False,
    )
    assert res.returncode == 0, res.stderr
    data = json.loads(res.stdout)
    assert len(data["modules"]) >= 10
    ros = [m for m in data["loaded"] if is_ros(m) or m.startswith("flexmotion_ros.nodes")]
    assert ros == [], f"importing the core loaded {ros}"

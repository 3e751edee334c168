"""The execution layer is ROS-free: no rclpy, messages, matplotlib, nodes, command line or plots."""

from __future__ import annotations

import ast
import subprocess
import sys
from pathlib import Path

import flexmotion_ros.execution as execution

EXECUTION = Path(__file__).resolve().parents[2] / "flexmotion_ros" / "execution"
FORBIDDEN = ("rclpy", "matplotlib", "flexmotion_ros.nodes", "flexmotion_ros.cli", "flexmotion_ros.plots")
MESSAGE_SUFFIXES = ("_msgs", "_srvs", "_interfaces")


def imported_modules(path: Path) -> list[str]:
    """Absolute names of the modules a file of ``flexmotion_ros.execution`` imports."""
    names = []
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.Import):
            names += [a.name for a in node.names]
        elif isinstance(node, ast.ImportFrom):
            if node.level == 0:
                names.append(node.module or "")
            else:  # relative to flexmotion_ros.execution
                base = ["flexmotion_ros", "execution"][: 3 - node.level]
                names += [".".join([*base, node.module or a.name]) for a in node.names]
    return names


def forbidden(names: list[str]) -> list[str]:
    return [n for n in names if n.startswith(FORBIDDEN) or n.split(".")[0].endswith(MESSAGE_SUFFIXES)]


def test_no_forbidden_import_in_the_source():
    files = sorted(EXECUTION.glob("*.py"))
    assert len(files) >= 4
    assert {f: forbidden(imported_modules(f)) for f in files} == {f: [] for f in files}


def test_a_forbidden_import_is_caught(tmp_path):
    bad = tmp_path / "bad.py"
    bad.write_text("from ..nodes import messages\nfrom std_msgs.msg import Float64\nimport numpy\n")
    assert forbidden(imported_modules(bad)) == ["flexmotion_ros.nodes", "std_msgs.msg"]


def test_importing_it_loads_no_ros():
    code = "import sys, flexmotion_ros.execution; print(sorted(m for m in sys.modules if m.startswith(('rclpy', 'std_msgs', 'matplotlib', 'flexmotion_ros.nodes'))))"
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout
    assert out.strip() == "[]"


def test_the_public_names_are_exported():
    assert all(hasattr(execution, name) for name in execution.__all__)
    assert {"CommandStream", "Segment", "HOLD", "splice_point", "lead_samples", "SplicePoint"} <= set(execution.__all__)

"""ament_python package flexmotion_ros (also pip-installable).

``colcon build`` installs the executables to ``lib/flexmotion_ros`` (see
setup.cfg) so that ``ros2 run flexmotion_ros planner`` finds them.  On a
machine without a ROS distro, ``pip install -e '.[ros]'`` brings ROS 2 Jazzy
from PyPI; it is optional and never required by the package itself.
"""

from glob import glob

from setuptools import find_packages, setup

package_name = "flexmotion_ros"

setup(
    name=package_name,
    version="0.1.0",
    packages=find_packages(exclude=["test", "test.*", "bench"]),
    data_files=[
        ("share/ament_index/resource_index/packages", ["resource/" + package_name]),
        ("share/" + package_name, ["package.xml"]),
        ("share/" + package_name + "/config", glob("config/*.yaml")),
    ],
    python_requires=">=3.10",
    # highspy: HiGHS directly, without linprog's per-call overhead (core/linear_program/; optional at
    # run time: without it linprog solves the same LPs)
    install_requires=["setuptools", "numpy", "scipy", "pyyaml", "matplotlib", "highspy>=1.16,<2"],
    extras_require={
        # ROS 2 Jazzy from PyPI, for machines without a ROS distro
        "ros": ["ros-jazzy-rclpy", "ros-jazzy-common-interfaces", "ros-jazzy-rmw-fastrtps-cpp"],
        "test": ["pytest", "hypothesis", "colcon-common-extensions", "ruff", "control"],
        "bench": ["casadi", "ruckig"],
        # compiled kernels of the planners' hot loops (core/kernels/); optional: without it the
        # numpy path (the reference) runs, with the same answers
        "fast": ["numba>=0.60"],
    },
    zip_safe=True,
    maintainer="flexmotion developers",
    maintainer_email="flexmotion@example.com",
    description="Time-optimal and input-shaped moves for flexible machines (ROS 2 Jazzy)",
    license="Apache-2.0",
    tests_require=["pytest"],
    entry_points={
        "console_scripts": [
            "flexmotion = flexmotion_ros.cli.main:entry",
            "planner = flexmotion_ros.nodes.planner_node:main",
            "plant = flexmotion_ros.nodes.plant_node:main",
        ],
    },
)

"""Files the package ships (parameter files, executables), found wherever it is installed.

A colcon (ament_python) install puts the parameter files in
``<prefix>/share/flexmotion_ros/config/`` and the executables in
``<prefix>/lib/flexmotion_ros/``; a pip install puts the parameter files in
``<sys.prefix>/share/flexmotion_ros/config/`` (setup.py ``data_files``) and the
console scripts in ``<sys.prefix>/bin``; a source checkout (``pip install -e``)
has them in ``config/``.  The share directories are searched in this order:

1. every prefix of ``AMENT_PREFIX_PATH``, in order (what the ament index and
   ``ament_index_python.get_package_share_directory`` do, without depending on
   ament_index_python, which the pip set-up does not install);
2. the prefix this package is installed under (a colcon install that was not
   sourced), then ``sys.prefix`` (a pip install);
3. the source checkout this module belongs to (``package.xml`` beside ``config/``).

The first directory that holds the requested file wins.
"""

from __future__ import annotations

import os
import shutil
import sys
from collections.abc import Mapping
from pathlib import Path

PACKAGE = "flexmotion_ros"
#: The parameter file ``flexmotion demo`` uses when no ``--config`` is given.
DEFAULT_CONFIG = "config/wie_bernstein.yaml"
#: This module's file: ``<root>/flexmotion_ros/cli/shipped.py`` (root: a source checkout or site-packages).
_HERE = Path(__file__).resolve()
#: The source checkout holding this module, if it is one (monkeypatched by the tests).
SOURCE_ROOT: Path | None = _HERE.parents[2] if (_HERE.parents[2] / "package.xml").is_file() else None


def _installed_prefix() -> Path | None:
    """``<prefix>`` when this package lives in ``<prefix>/lib/pythonX.Y/{site,dist}-packages/``, else None."""
    site = _HERE.parents[2]
    if site.name in ("site-packages", "dist-packages") and site.parent.parent.name == "lib":
        return site.parents[2]
    return None


def _prefixes(environ: Mapping[str, str], sys_prefix: str) -> list[Path]:
    """Install prefixes in search order, without repeats: AMENT_PREFIX_PATH, this package's, ``sys_prefix``."""
    found: list[Path] = [Path(p) for p in environ.get("AMENT_PREFIX_PATH", "").split(os.pathsep) if p]
    own = _installed_prefix()
    if own is not None:
        found.append(own)
    found.append(Path(sys_prefix))
    out: list[Path] = []
    for p in found:
        if p not in out:
            out.append(p)
    return out


def share_directories(environ: Mapping[str, str] | None = None, sys_prefix: str | None = None) -> list[Path]:
    """Every directory that may hold the shipped files, in search order (they need not exist).

    Parameters
    ----------
    environ
        Environment to read ``AMENT_PREFIX_PATH`` from (default ``os.environ``).
    sys_prefix
        The Python installation prefix (default ``sys.prefix``).

    Returns
    -------
    list of Path
        ``<prefix>/share/flexmotion_ros`` for each install prefix, then the source checkout.
    """
    env = os.environ if environ is None else environ
    dirs = [p / "share" / PACKAGE for p in _prefixes(env, sys.prefix if sys_prefix is None else sys_prefix)]
    if SOURCE_ROOT is not None:
        dirs.append(SOURCE_ROOT)
    return dirs


def find_shipped(relative: str, environ: Mapping[str, str] | None = None, sys_prefix: str | None = None) -> Path | None:
    """The first shipped file ``relative`` (e.g. ``"config/crane.yaml"``) in :func:`share_directories`.

    Returns
    -------
    Path or None
        The file, or None where no share directory holds it.
    """
    for d in share_directories(environ, sys_prefix):
        candidate = d / relative
        if candidate.is_file():
            return candidate
    return None


def find_executable(name: str, environ: Mapping[str, str] | None = None, sys_prefix: str | None = None) -> Path | None:
    """An installed executable of the package (``flexmotion``, ``planner``, ``plant``).

    Looks in ``<prefix>/lib/flexmotion_ros/`` (where ``colcon build`` puts
    them and ``ros2 run`` looks) for every prefix of :func:`share_directories`,
    then in ``<sys_prefix>/bin`` and beside the running interpreter (a pip
    install), then on ``PATH``.

    Returns
    -------
    Path or None
        The executable file, or None.
    """
    env = os.environ if environ is None else environ
    prefix = sys.prefix if sys_prefix is None else sys_prefix
    candidates = [p / "lib" / PACKAGE / name for p in _prefixes(env, prefix)]
    candidates += [Path(prefix) / "bin" / name, Path(sys.executable).parent / name]
    on_path = shutil.which(name, path=env.get("PATH", os.defpath))
    if on_path is not None:
        candidates.append(Path(on_path))
    for c in candidates:
        if c.is_file() and os.access(c, os.X_OK):
            return c
    return None

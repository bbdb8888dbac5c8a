"""Create the simulator environment: ``python -m segadeform.physics.setup [DIR]``.

Makes a virtual environment (default: ``.venv-sim`` at the repository root)
with Python 3.11 and the pinned ``bpy`` of ``requirements-blender.txt``.
Blender stays out of segadeform's own environment: it is GPL-3.0, exists for
Python 3.11 only and pins numpy<2.  The interpreter used is the first of
``--python``, ``python3.11`` on PATH, or this interpreter if it is 3.11.
"""

from __future__ import annotations

import argparse
import shutil
import subprocess
import sys
from pathlib import Path

from ..errors import SimulationError

REQUIREMENTS = Path(__file__).with_name("requirements-blender.txt")


def _python311(explicit):
    if explicit:
        return explicit
    p = shutil.which("python3.11")
    if p:
        return p
    if sys.version_info[:2] == (3, 11):
        return sys.executable
    raise SimulationError("bpy needs Python 3.11 and none was found; pass --python /path/to/python3.11")


def setup_sim_env(target: Path, python=None, *, quiet: bool = True) -> Path:
    """Create (or update) the environment at ``target``; returns its Python."""
    target = Path(target)
    exe = target / "bin" / "python"
    if not exe.is_file():
        subprocess.run([_python311(python), "-m", "venv", str(target)], check=True)
    cmd = [str(exe), "-m", "pip", "install", "-r", str(REQUIREMENTS)] + (["-q"] if quiet else [])
    subprocess.run(cmd, check=True)
    from .blender import WORKER

    out = subprocess.run([str(exe), str(WORKER), "--version"], check=True, capture_output=True, text=True)
    if not out.stdout.strip():
        raise SimulationError(f"bpy did not import in {target}")
    return exe


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(prog="python -m segadeform.physics.setup", description=__doc__.splitlines()[0])
    ap.add_argument("target", nargs="?", default=str(Path(__file__).resolve().parents[3] / ".venv-sim"))
    ap.add_argument("--python", help="a Python 3.11 interpreter")
    a = ap.parse_args(argv)
    try:
        exe = setup_sim_env(Path(a.target), a.python)
    except (SimulationError, subprocess.CalledProcessError) as e:
        sys.stderr.write(f"Error: {e}\n")
        return 1
    sys.stdout.write(f"simulator environment ready: {exe}\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())

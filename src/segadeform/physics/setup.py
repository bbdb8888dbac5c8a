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


def worker_env_path() -> Path:
    """Where :func:`ensure_sim_python` makes the simulator environment of a worker machine: the user
    cache (:func:`segadeform.io.cache.cache_dir`), named by the pinned requirements."""
    import hashlib

    from ..io.cache import cache_dir

    digest = hashlib.sha256(REQUIREMENTS.read_bytes()).hexdigest()[:12]
    return cache_dir() / f"sim-env-{digest}"


def ensure_sim_python(explicit=None, *, target: Path | None = None, setup=None) -> Path:
    """The simulator's Python, made on first use where there is none (each worker of a cluster).

    Found as :func:`~segadeform.physics.blender.find_sim_python` finds it (``explicit``,
    ``SEGADEFORM_SIM_PYTHON``, ``.venv-sim`` of a source checkout); a Python named by ``explicit`` or the
    environment variable that does not exist is an error, not made.  Otherwise the environment at
    ``target`` (default :func:`worker_env_path`) is used, made by ``setup(target)`` (default
    :func:`setup_sim_env`: Python 3.11 and PyPI needed) the first time: one process of the machine
    makes it under a file lock while the others wait, and a marker written last says it is complete.
    """
    import os

    from .blender import find_sim_python

    try:
        return find_sim_python(explicit)
    except SimulationError:
        if explicit or os.environ.get("SEGADEFORM_SIM_PYTHON"):
            raise
    target = Path(target) if target is not None else worker_env_path()
    exe = target / "bin" / "python"
    ready = target / ".segadeform-ready"
    if ready.is_file() and exe.is_file():
        return exe
    target.parent.mkdir(parents=True, exist_ok=True)
    with _file_lock(target.with_name(target.name + ".lock")):
        if not (ready.is_file() and exe.is_file()):  # another process may have made it meanwhile
            try:
                made = (setup or setup_sim_env)(target)
            except (subprocess.CalledProcessError, OSError) as e:
                raise SimulationError(
                    f"could not make the simulator environment in {target} (expected "
                    f"`python -m segadeform.physics.setup {target}` to succeed, got {e})"
                ) from None
            if made is not None:
                exe = Path(made)
            if not exe.is_file():
                raise SimulationError(f"the simulator environment in {target} has no Python (expected {exe})")
            from ..io.atomic import atomic_path

            with atomic_path(ready) as tmp:
                Path(tmp).write_text(REQUIREMENTS.read_text())
    return exe


class _file_lock:
    """An exclusive lock on a file, held across processes of one machine (POSIX ``flock``; elsewhere none)."""

    def __init__(self, path: Path) -> None:
        self.path = path

    def __enter__(self):
        self.fh = open(self.path, "a")
        try:
            import fcntl
        except ImportError:  # Windows: no lock (workers of a cluster run POSIX)
            return self
        fcntl.flock(self.fh.fileno(), fcntl.LOCK_EX)
        return self

    def __exit__(self, *exc) -> None:
        self.fh.close()  # releases the lock


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

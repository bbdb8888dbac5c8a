from __future__ import annotations

import contextlib
import os
from collections.abc import Callable, Iterator
from pathlib import Path

# Under pytest-xdist (`.ci/run`: a worker per core) each worker gets its share of the cores for torch's and the BLAS's
# threads, set before numpy or torch is first imported: two workers of two threads each on two cores ran the
# BLAS- and torch-bound tests 3-5x slower than alone.  A variable the user set is kept.
_WORKERS = int(os.environ.get("PYTEST_XDIST_WORKER_COUNT") or 1)
if _WORKERS > 1:
    _cores = len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else os.cpu_count() or 1
    for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
        os.environ.setdefault(_var, str(max(1, _cores // _WORKERS)))

import numpy as np  # noqa: E402 (after the thread counts above)
import pytest  # noqa: E402

REPO = Path(__file__).resolve().parents[1]
SAMPLES = REPO / "samples"


@pytest.fixture
def samples() -> Path:
    return SAMPLES


@pytest.fixture
def rest_joints() -> np.ndarray:
    return np.load(SAMPLES / "skeletons" / "tpose_joints_24.npy")


@contextlib.contextmanager
def run_lock(tmp_path_factory, name: str) -> Iterator[Path | None]:
    """Under pytest-xdist, held while no other worker of this run holds the lock ``name``; yields the run's folder
    (above each worker's own, where the lock lies).  In one process there is nothing to wait for: yields None."""
    if not os.environ.get("PYTEST_XDIST_WORKER"):
        yield None
        return
    from filelock import FileLock

    root = tmp_path_factory.getbasetemp().parent
    with FileLock(str(root / f"{name}.lock")):
        yield root


def made_once(tmp_path_factory, name: str, make: Callable[[Path], object]) -> Path:
    """Folder ``name``, made by ``make(path)`` once per test run: in this process, or under pytest-xdist by the first
    worker that asks while the others wait on a lock and then use it (a package export costs a minute or two; each
    worker making its own doubled the suite's heaviest fixtures).  ``make`` must give the same folder whichever
    worker runs it; a marker written after it returns says the folder is complete (a worker whose ``make`` failed
    leaves none, and the next one to ask makes it again)."""
    with run_lock(tmp_path_factory, name) as root:
        if root is None:
            path = tmp_path_factory.mktemp(name) / name
            make(path)
            return path
        path, done = root / name, root / f"{name}.done"
        if not done.exists():
            make(path)
            done.touch()
    return path


def split_at_a_seam(m):
    """The mesh ``m`` split along its centre line, as game-engine exports split vertices at UV seams: the vertices
    of faces on both sides of x = 0 copied (appended) for the faces on the +x side.  Returns the vertices, the faces
    and the count copied."""
    side = m.vertices[m.faces].mean(axis=1)[:, 0] > 0
    shared = np.intersect1d(np.unique(m.faces[side]), np.unique(m.faces[~side]))
    copy = np.arange(len(m.vertices))
    copy[shared] = len(m.vertices) + np.arange(len(shared))
    faces = m.faces.copy()
    faces[side] = copy[faces[side]]
    return np.concatenate([m.vertices, m.vertices[shared]]), faces, len(shared)


def leftovers(directory: Path) -> list[str]:
    """Temporary files a failed write might have left (atomic writes use '.NAME.tmp-*')."""
    return sorted(p.name for p in Path(directory).iterdir() if ".tmp-" in p.name)


@pytest.fixture(scope="session")
def sim_python():
    """The simulator environment; CI makes it (.ci/run), so these tests run there."""
    from segadeform.errors import SimulationError
    from segadeform.physics import find_sim_python

    try:
        return find_sim_python()
    except SimulationError as e:
        pytest.skip(f"no simulator environment here ({e}); `python -m segadeform.physics.setup` makes one")


@pytest.fixture(scope="session")
def random_model(tmp_path_factory):
    """(frozen torch SEGANet, its model package with every deformer variant), made once per session."""
    torch = pytest.importorskip("torch", reason="exporting a package needs the 'torch' extra")
    from segadeform.export import export_package
    from segadeform.model import ModelConfig, SEGANet

    torch.manual_seed(3)
    net = SEGANet(ModelConfig()).eval()
    with torch.no_grad():  # as after training: the residual corrections on, so every path is exercised
        net.weight_gate.fill_(0.7)
        net.blend_gate.fill_(0.5)
    path = made_once(tmp_path_factory, "random", lambda p: export_package(net, p, check=False))
    return net.freeze(), path


@pytest.fixture(scope="session")
def random_package(random_model):
    return random_model[1]


def _dqs_net(seed: int, motion_input: str = "pose"):
    """A DQS network as after training (residual corrections on): the portable scene's skinning, so that the model's
    own deformer is the one the scene runs and a package needs no other variant."""
    import torch

    from segadeform.model import ModelConfig, SEGANet

    torch.manual_seed(seed)
    net = SEGANet(ModelConfig(skinning="dqs", motion_input=motion_input)).eval()
    with torch.no_grad():
        net.weight_gate.fill_(0.5 + 0.2 * (seed - 5))
        net.blend_gate.fill_(0.5)
    return net


@pytest.fixture(scope="session")
def heading_model(tmp_path_factory):
    """(frozen network whose motion processors read the root's rotation relative to the heading, its package: the
    model's own deformer and the body graphs), made once per run: tests/export checks its graphs, tests/runtimes runs
    it in every runtime."""
    pytest.importorskip("torch", reason="exporting a package needs the 'torch' extra")
    from segadeform.export import export_package

    net = _dqs_net(5, "heading")
    path = made_once(tmp_path_factory, "variant-heading", lambda p: export_package(net, p, check=False, variants=False))
    return net.freeze(), path


@pytest.fixture(scope="session")
def ensemble_model(tmp_path_factory):
    """(frozen ensemble of two DQS networks, its package as heading_model's, the two members), made once per run:
    tests/model checks it against torch, tests/runtimes runs it in every runtime."""
    pytest.importorskip("torch", reason="exporting a package needs the 'torch' extra")
    from segadeform.export import export_package
    from segadeform.model.ensemble import combine

    members = [_dqs_net(5), _dqs_net(6)]
    ens = combine(members)
    path = made_once(
        tmp_path_factory, "variant-ensemble", lambda p: export_package(ens, p, check=False, variants=False)
    )
    return ens.freeze(), path, members


@pytest.fixture(scope="session", autouse=True)
def _user_cache(tmp_path_factory):
    """The suite's runs cache into a folder of its own, never the user's cache."""
    import os

    d = tmp_path_factory.mktemp("user-cache")
    old = os.environ.get("SEGADEFORM_CACHE_DIR")
    os.environ["SEGADEFORM_CACHE_DIR"] = str(d)
    yield d
    if old is None:
        os.environ.pop("SEGADEFORM_CACHE_DIR", None)
    else:
        os.environ["SEGADEFORM_CACHE_DIR"] = old


# the packages a run exports once (made_once), in the order the second worker makes them
_PACKAGES = ("random_model", "heading_model", "ensemble_model")


@pytest.fixture(scope="session", autouse=True)
def _packages_first(request, _user_cache):  # (after the suite's own cache folder is set)
    """Under pytest-xdist, the second worker (gw1) makes the run's packages before its first test, while the others
    run tests that need none (the test files in alphabetical order: tests/body ... tests/distributed need none).
    Otherwise every worker reached the first test that needs one at about the same time, and all but one waited on
    its lock for the four minutes of the export.  Only the packages some collected test uses are made; in one process
    nothing changes (each is made when first used)."""
    if os.environ.get("PYTEST_XDIST_WORKER") != "gw1":
        return
    used = set().union(*(getattr(item, "fixturenames", ()) for item in request.session.items))
    for name in _PACKAGES:
        if name in used or (name == "random_model" and "random_package" in used):
            try:
                request.getfixturevalue(name)
            except (Exception, pytest.skip.Exception):  # no torch here, or the export fails: the tests that use the
                return  # package get the skip or the error (pytest keeps a session fixture's), not every test here

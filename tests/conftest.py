from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

REPO = Path(__file__).resolve().parents[1]
SAMPLES = REPO / "samples"


@pytest.fixture
def samples() -> Path:
    return SAMPLES


@pytest.fixture
def rest_joints() -> np.ndarray:
    return np.load(SAMPLES / "skeletons" / "tpose_joints_24.npy")


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
    path = tmp_path_factory.mktemp("pkg") / "random"
    export_package(net, path, check=False)
    return net.freeze(), path


@pytest.fixture(scope="session")
def random_package(random_model):
    return random_model[1]


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

"""Physics self-supervision: the cloth energies against closed forms, and the pairs never leak held-out data."""

import numpy as np
import pytest
import torch

from segadeform.errors import InputError
from segadeform.geometry.primitives import cylinder, grid_plane
from segadeform.train.energies import Material, cloth_energy, cloth_topology, dihedral_angles


def _t(x):
    return torch.as_tensor(np.asarray(x, np.float32))


def _grid():
    v, f = grid_plane(9, 9, (0.4, 0.4))
    return v, f


def test_rest_has_no_stretch_or_bending_and_gravity_is_the_mean_height():
    v, f = _grid()
    v = v + [0.0, 1.25, 0.0]
    topo = cloth_topology(v, f)
    e = cloth_energy(_t(v)[None], topo, Material())
    assert float(e["stretch"]) == pytest.approx(0.0, abs=1e-8)  # float32 lengths
    assert float(e["bend"]) == pytest.approx(0.0, abs=1e-9)
    # E_gravity / (M g) = mass-weighted mean height; a uniform grid's is its height
    assert float(e["gravity"]) == pytest.approx(1.25, rel=1e-6)
    assert float(e["inertia"]) == 0.0 and float(e["collision"]) == 0.0


def test_uniform_scaling_gives_the_spring_energy_in_closed_form():
    v, f = _grid()
    topo = cloth_topology(v, f)
    mat = Material(gravity=9.81)
    s = 0.01
    e = cloth_energy(_t(v * (1 + s))[None], topo, mat)
    area = 0.4 * 0.4
    # every edge strains by s; sum of the edge areas is the total area
    expect = 0.5 * mat.stretch * area * s**2 / (mat.density * area * mat.gravity)
    assert float(e["stretch"]) == pytest.approx(expect, rel=1e-3)


def test_folding_costs_bending_quadratic_in_the_angle_and_is_smooth_when_flat():
    v, f = _grid()
    topo = cloth_topology(v, f)

    # fold the grid about the line x = 0.2 (the middle column of vertices) by angle a
    def folded(a):
        w = v.copy()
        right = w[:, 0] > 0.2 + 1e-9
        r = w[right, 0] - 0.2
        w[right, 0] = 0.2 + r * np.cos(a)
        w[right, 1] = r * np.sin(a)
        return w

    e1 = float(cloth_energy(_t(folded(0.1))[None], topo, Material())["bend"])
    e2 = float(cloth_energy(_t(folded(0.2))[None], topo, Material())["bend"])
    assert e1 > 0 and e2 / e1 == pytest.approx(4.0, rel=0.02)
    x = _t(v)[None].requires_grad_(True)
    cloth_energy(x, topo, Material())["total"].backward()
    assert torch.isfinite(x.grad).all()
    # the fold's angle is seen with its sign
    th = dihedral_angles(_t(folded(0.3))[None], topo.hinges)[0]
    assert float(th.abs().max()) == pytest.approx(0.3, abs=1e-4)


def test_a_curved_rest_shape_is_its_own_zero_of_bending():
    v, f = cylinder(24, 6, radius=0.15, height=0.3)
    topo = cloth_topology(v, f)
    assert float(topo.hinge_rest.abs().max()) > 0.1  # curved at rest
    e = cloth_energy(_t(v)[None], topo, Material())
    assert float(e["bend"]) == pytest.approx(0.0, abs=1e-9)
    # a rigid motion changes neither stretch nor bending
    r = np.array([[0.0, -1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]])
    e = cloth_energy(_t(v @ r.T + 0.3)[None], topo, Material())
    assert float(e["bend"]) == pytest.approx(0.0, abs=1e-7)
    assert float(e["stretch"]) == pytest.approx(0.0, abs=1e-9)


def test_inertia_is_zero_for_constant_velocity_and_counts_acceleration():
    v, f = _grid()
    topo = cloth_topology(v, f)
    vel = np.array([0.1, 0.0, 0.2]) / 30
    x0, x1, x2 = (_t(v + k * vel)[None] for k in range(3))
    assert float(cloth_energy(x2, topo, Material(), prev=x1, prev2=x0)["inertia"]) == pytest.approx(0.0, abs=1e-9)
    a = 0.002  # metres of second difference
    x2b = x2 + torch.tensor([0.0, a, 0.0])
    mat = Material()
    # sum m a^2 / (2 h^2) / (M g) = a^2 / (2 h^2 g)
    got = float(cloth_energy(x2b, topo, mat, prev=x1, prev2=x0, dt=1 / 30)["inertia"])
    assert got == pytest.approx(a**2 * 900 / (2 * mat.gravity), rel=1e-3)


def test_collision_costs_only_inside_the_margin():
    v, f = _grid()
    topo = cloth_topology(v, f)
    mat = Material(margin=0.003)
    n = np.tile([0.0, 1.0, 0.0], (len(v), 1))
    far = cloth_energy(_t(v)[None], topo, mat, contact_p=_t(v - [0, 0.01, 0])[None], contact_n=_t(n)[None])
    assert float(far["collision"]) == 0.0
    inside = cloth_energy(_t(v)[None], topo, mat, contact_p=_t(v + [0, 0.002, 0])[None], contact_n=_t(n)[None])
    expect = mat.collision * 0.4 * 0.4 * 0.005**3 / (mat.density * 0.4 * 0.4 * mat.gravity)
    assert float(inside["collision"]) == pytest.approx(expect, rel=1e-3)


def test_bad_materials_and_meshes_are_refused():
    with pytest.raises(InputError, match="density"):
        Material(density=0.0)
    with pytest.raises(InputError, match="stretch"):
        Material(stretch=float("nan"))
    with pytest.raises(InputError, match="triangles"):
        cloth_topology(np.zeros((3, 3)), np.zeros((0, 3), int))


_PAIRS = """
[dataset]
fps = 30.0
seconds = 0.3
held_out_kinds = ["shorts"]
held_out_motions = ["arm_swing"]
[simulate]
effects = ["gravity"]
[[garments]]
kind = "skirt"
resolution = 600
[[garments]]
kind = "shorts"
resolution = 600
split = "test"
[[bodies]]
betas = []
[[bodies]]
betas = [1.0]
split = "test"
[[motions]]
kind = "walk"
ease_in = 0.0
[[motions]]
kind = "arm_swing"
split = "test"
"""


@pytest.fixture
def pairs_config(tmp_path):
    p = tmp_path / "pairs.toml"
    p.write_text(_PAIRS)
    return p


def test_pairs_are_training_pairs_only_and_carry_what_the_energies_need(pairs_config, tmp_path, body):
    from segadeform.train.energies import PhysicsPairs

    pairs = PhysicsPairs(pairs_config, tmp_path / "cache", body, n_star=16, window=3, n_betas=10)
    assert [p.id for p in pairs.plan] == ["skirt-0__b0__walk-s0"]  # no held-out kind, motion or body
    it = pairs.item(0)
    n = it.rest.shape[0]
    assert it.features.shape[:2] == (1, n) and it.windows.shape[0] == it.n_frames == 9
    assert it.posed_body.shape == (9, body.n_vertices, 3)
    assert torch.allclose(it.body_weights.sum(-1), torch.ones(n), atol=1e-5)
    assert pairs.item(0) is it  # made once


def test_training_with_physics_logs_the_energy_and_lowers_it(synthetic_dataset, pairs_config, tmp_path, body):
    from segadeform.model.network import SEGANet
    from segadeform.train.config import load_train_config
    from segadeform.train.energies import PhysicsPairs
    from segadeform.train.trainer import physics_losses, train

    cfg_path = tmp_path / "train.toml"
    cfg_path.write_text(
        "[model]\nhidden = 16\nlstm_hidden = 16\nwindow = 3\nn_star = 16\n"
        "[optim]\nsteps = 4\nframes = 3\ncheckpoint_every = 2\nlr = 0.003\n"
        '[physics]\npairs = "pairs.toml"\nevery = 1\nframes = 4\n'
    )
    cfg = load_train_config(cfg_path, dataset=synthetic_dataset)
    run = tmp_path / "run"
    train(cfg, run, body, log_every=1)
    rows = (run / "loss.csv").read_text().splitlines()
    head = rows[0].split(",")
    col = head.index("physics")
    vals = [float(r.split(",")[col]) for r in rows[1:]]
    assert len(vals) == 4 and all(np.isfinite(vals)) and all(v != 0 for v in vals)
    # the energy alone, minimised on one pair, goes down
    torch.manual_seed(0)
    model = SEGANet(cfg.model)
    pair = PhysicsPairs(pairs_config, tmp_path / "cache", body, n_star=16, window=3, n_betas=10).item(0)
    opt = torch.optim.Adam(model.parameters(), lr=3e-3)
    mat = cfg.physics.material()
    first = None
    for _ in range(15):
        e = physics_losses(model, pair, 2, 4, mat, np.asarray(body.faces), torch.device("cpu"))["total"]
        first = float(e.detach()) if first is None else first
        opt.zero_grad()
        e.backward()
        opt.step()
    assert float(e) < first


def test_physics_configs_are_checked(tmp_path, synthetic_dataset):
    from segadeform.errors import FileFormatError
    from segadeform.train.config import load_train_config

    p = tmp_path / "t.toml"
    p.write_text("[physics]\nevery = 2\n")
    with pytest.raises(FileFormatError, match="needs physics.pairs"):
        load_train_config(p, dataset=synthetic_dataset)
    p.write_text('[physics]\nevery = 2\npairs = "nowhere.toml"\n')
    with pytest.raises(FileFormatError, match="not a file"):
        load_train_config(p, dataset=synthetic_dataset)
    p.write_text("[physics]\nframes = 2\n")
    with pytest.raises(FileFormatError, match="frames"):
        load_train_config(p, dataset=synthetic_dataset)


def test_training_time_is_wall_time_with_physics(synthetic_dataset, pairs_config, tmp_path, body):
    """The physics term's frame draw once overwrote the trainer's timer (train_seconds was wrong)."""
    import json
    import time

    from segadeform.train.config import load_train_config
    from segadeform.train.trainer import train

    cfg_path = tmp_path / "train.toml"
    cfg_path.write_text(
        "[model]\nhidden = 16\nlstm_hidden = 16\nwindow = 3\nn_star = 16\n"
        "[optim]\nsteps = 3\nframes = 2\ncheckpoint_every = 3\n"
        '[physics]\npairs = "pairs.toml"\nevery = 1\nframes = 4\n'
    )
    t0 = time.perf_counter()
    train(load_train_config(cfg_path, dataset=synthetic_dataset), tmp_path / "run", body)
    wall = time.perf_counter() - t0
    took = json.loads((tmp_path / "run" / "train.json").read_text())["train_seconds"]
    assert 0 < took <= wall


def test_prefetched_pairs_resume_to_the_same_model(synthetic_dataset, pairs_config, tmp_path, body):
    """physics.prefetch builds the next pair in a thread from a stream of its own: a run stopped and resumed
    draws the same pairs and ends with the same weights as one never stopped."""
    import csv

    from segadeform.train.config import load_train_config
    from segadeform.train.trainer import train

    # three training pairs (the fixture's one, two more motions): a stream that lost its place draws others
    pairs_config.write_text(
        _PAIRS
        + '[[motions]]\nname = "walk-fast"\nkind = "walk"\nspeed = 1.4\nease_in = 0.0\n'
        + '[[motions]]\nkind = "dance"\nease_in = 0.0\n'
    )
    cfg_path = tmp_path / "train.toml"
    cfg_path.write_text(
        "[model]\nhidden = 16\nlstm_hidden = 16\nwindow = 3\nn_star = 16\n"
        "[optim]\nsteps = 6\nframes = 2\ncheckpoint_every = 3\nlr = 0.003\n"
        '[physics]\npairs = "pairs.toml"\nevery = 1\nframes = 4\nprefetch = true\n'
    )
    cfg = load_train_config(cfg_path, dataset=synthetic_dataset)
    a = train(cfg, tmp_path / "a", body, log_every=3)

    def stop(step, row):
        if step == 3:
            raise KeyboardInterrupt

    with pytest.raises(KeyboardInterrupt):
        train(cfg, tmp_path / "b", body, log_every=3, progress=stop)
    ck = torch.load(tmp_path / "b" / "last.pt", weights_only=False)
    assert ck["pairs"]["ahead"] is not None  # the index drawn ahead is part of the checkpoint
    b = train(cfg, tmp_path / "b", body, log_every=3)
    sa, sb = torch.load(a, weights_only=True)["state_dict"], torch.load(b, weights_only=True)["state_dict"]
    assert max(float((sa[k].float() - sb[k].float()).abs().max()) for k in sa) < 1e-6
    rows_a = list(csv.DictReader(open(tmp_path / "a" / "loss.csv")))
    rows_b = list(csv.DictReader(open(tmp_path / "b" / "loss.csv")))
    assert [r["physics"] for r in rows_a] == [r["physics"] for r in rows_b]
    assert all(float(r["physics"]) != 0 for r in rows_a)
    # the stream draws several pairs (so the equality above is about which pairs, not only one pair's energy)
    from segadeform.train.energies import PhysicsPairs
    from segadeform.train.trainer import _PairPrefetch

    pairs = PhysicsPairs(pairs_config, tmp_path / "cache", body, n_star=16, window=3, n_betas=10)
    assert len(pairs) == 3
    pf = _PairPrefetch(pairs, 0)
    drawn = [pf.next().id for _ in range(6)]
    pf.close()
    assert len(set(drawn)) >= 2


def test_pair_motions_are_cached_and_serve_a_machine_without_the_capture_file(tmp_path, body):
    """A pair's motion clip is made once into the cache's motions/; with the capture file gone (a machine
    without ../shared) the cached clip is what the pair gets, the same numbers."""
    import shutil

    from segadeform.train.energies import PhysicsPairs

    from ..conftest import SAMPLES

    (tmp_path / "mocap").mkdir()
    shutil.copyfile(SAMPLES / "motions" / "cmu" / "02_01_walk.bvh", tmp_path / "mocap" / "02_01_walk.bvh")
    cfg = tmp_path / "pairs.toml"
    cfg.write_text(
        _PAIRS.replace('[[motions]]\nkind = "walk"\nease_in = 0.0\n', '[[motions]]\nfile = "mocap/02_01_walk.bvh"\n')
    )
    a = PhysicsPairs(cfg, tmp_path / "cache", body, n_star=16, window=3, n_betas=10).item(0)
    assert len(list((tmp_path / "cache" / "motions").glob("motion-*.npz"))) == 1
    (tmp_path / "mocap" / "02_01_walk.bvh").unlink()
    b = PhysicsPairs(cfg, tmp_path / "cache", body, n_star=16, window=3, n_betas=10).item(0)
    assert torch.equal(a.windows, b.windows) and torch.equal(a.trans, b.trans)
    assert np.array_equal(a.posed_body, b.posed_body) and a.fps == b.fps


def test_pairs_of_a_makehuman_garment_train_from_the_cache_without_its_files(tmp_path, body):
    """A machine without ../shared: the MakeHuman garment made beside it is in the cache, the config loads
    without the .mhclo and the pair is the same garment."""
    import shutil

    from segadeform.dataset.config import load_dataset_config
    from segadeform.errors import FileFormatError
    from segadeform.train.energies import PhysicsPairs

    from ..conftest import SAMPLES

    mh = tmp_path / "mh"
    mh.mkdir()
    for f in ("skirt_short_f.mhclo", "skirt_short_f.obj"):
        shutil.copyfile(SAMPLES / "garments" / "makehuman" / f, mh / f)
    cfg = tmp_path / "pairs.toml"
    cfg.write_text(
        _PAIRS.replace(
            '[[garments]]\nkind = "skirt"\nresolution = 600\n',
            '[[garments]]\nname = "mh-skirt"\nkind = "skirt"\nmhclo = "mh/skirt_short_f.mhclo"\n',
        )
    )
    a = PhysicsPairs(cfg, tmp_path / "cache", body, n_star=16, window=3, n_betas=10).item(0)
    shutil.rmtree(mh)
    with pytest.raises(FileFormatError, match="mhclo does not exist"):
        load_dataset_config(cfg)  # making a dataset still needs the file
    b = PhysicsPairs(cfg, tmp_path / "cache", body, n_star=16, window=3, n_betas=10).item(0)
    assert torch.equal(a.rest, b.rest) and torch.equal(a.features, b.features)
    # a cached garment made for another body shape is refused, not used (its file is not here to remake it)
    from segadeform.errors import InputError

    other = tmp_path / "other.toml"
    other.write_text(cfg.read_text().replace("[[bodies]]\nbetas = []", "[[bodies]]\nbetas = [0.5]", 1))
    shutil.copytree(tmp_path / "cache", tmp_path / "cache2")
    with pytest.raises(InputError, match="made from another garment, body or file"):
        PhysicsPairs(other, tmp_path / "cache2", body, n_star=16, window=3, n_betas=10).item(0)

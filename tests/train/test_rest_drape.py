"""``ModelConfig.rest_drape``: the deformer skins the garment moved toward its drape at rest, in training, in
evaluation and against the non-learned ``lbs-drape``; old checkpoints read as 0; the package format refuses it."""

from __future__ import annotations

import json

import numpy as np
import pytest

torch = pytest.importorskip("torch")

from segadeform.body.drape import drape_rest  # noqa: E402
from segadeform.dataset.store import list_samples, load_sample  # noqa: E402
from segadeform.errors import InputError  # noqa: E402
from segadeform.model import ModelConfig, SEGANet, save_checkpoint  # noqa: E402
from segadeform.train import load_train_config  # noqa: E402
from segadeform.train.predictors import LBSPredictor, make_predictor  # noqa: E402
from segadeform.train.trainer import train  # noqa: E402


def test_the_config_field_is_checked_and_old_configs_read_as_zero():
    assert ModelConfig.from_dict({"hidden": 32}).rest_drape == 0.0
    assert ModelConfig(rest_drape=0.5).rest_drape == 0.5
    for bad in (-0.1, 1.5, True, "0.5"):
        with pytest.raises(InputError, match="rest_drape"):
            ModelConfig(rest_drape=bad)


def test_lbs_drape_is_smooth_weights_on_the_draped_rest(synthetic_dataset, body):
    s = load_sample(synthetic_dataset, "skirt__b0__swing")
    p = make_predictor("d", "lbs-drape")
    assert isinstance(p, LBSPredictor) and p.prior == "smooth" and p.drape == 1.0
    d = drape_rest(s.rest, s.faces, body.shaped_vertices()[0], body.faces)
    assert np.abs(d - s.rest).max() > 1e-3  # the synthetic skirt does hang
    out = p.predict(s, body, None)
    ref = LBSPredictor("smooth")
    s_draped = type(s)(**{**s.__dict__, "rest": d})
    np.testing.assert_allclose(out, ref.predict(s_draped, body, None), atol=1e-12)


@pytest.mark.parametrize("amount", [0.0, 1.0])
def test_an_untrained_model_is_its_prior_on_the_rest_it_was_told_to_skin(synthetic_dataset, body, tmp_path, amount):
    """A residual model starts as LBS with its prior's weights: with rest_drape it is ``lbs-drape`` (amount 1),
    without it ``lbs-smooth``; the checkpoint predictor drapes as the trainer does."""
    torch.manual_seed(0)
    net = SEGANet(ModelConfig(hidden=16, lstm_hidden=16, weight_prior="smooth", rest_drape=amount))
    ck = save_checkpoint(tmp_path / "m.pt", net)
    s = load_sample(synthetic_dataset, "skirt__b0__swing")
    from segadeform.train.data import sample_asset

    asset = sample_asset(synthetic_dataset, s, body, net.cfg.n_star)
    got = make_predictor("m", str(ck)).predict(s, body, asset)
    want = LBSPredictor("smooth", drape=amount).predict(s, body, None)
    # float32 and the residual's log(w + eps) through the network: within 0.2 mm; the drape moves the skirt more
    np.testing.assert_allclose(got, want, atol=2e-4)
    other = LBSPredictor("smooth", drape=1.0 - amount).predict(s, body, None)
    assert np.abs(got - other).max() > 5e-3


def test_training_with_a_drape_runs_and_records_it(synthetic_dataset, body, tmp_path):
    p = tmp_path / "t.toml"
    p.write_text(
        '[model]\nhidden = 16\nlstm_hidden = 16\nweight_prior = "smooth"\nrest_drape = 0.5\n'
        "[optim]\nsteps = 3\nframes = 3\nlr = 0.003\n"
    )
    cfg = load_train_config(p, dataset=synthetic_dataset)
    ck = train(cfg, tmp_path / "run", body, val_ids=list_samples(synthetic_dataset, "test"))
    info = json.loads((tmp_path / "run" / "train.json").read_text())
    assert info["config"]["model"]["rest_drape"] == 0.5
    assert torch.load(ck, weights_only=True)["config"]["rest_drape"] == 0.5


def test_the_package_format_refuses_a_draped_model(tmp_path):
    from segadeform.export import export_package

    net = SEGANet(ModelConfig(hidden=16, lstm_hidden=16, rest_drape=0.5))
    with pytest.raises(InputError, match="drape"):
        export_package(net, tmp_path / "pkg", check=False, variants=False)
    assert not (tmp_path / "pkg").exists()


def test_a_mistyped_model_path_is_named_as_missing(tmp_path):
    """`eval -m shipped=samples/models/nope` said "a model must be 'simulation', 'lbs', ..." (a researcher's trial):
    a path that is not there is named as missing, one that is neither a package folder nor a checkpoint as such."""
    from segadeform.errors import FileFormatError, InputError
    from segadeform.train.predictors import make_predictor

    with pytest.raises(FileFormatError, match="no such model package folder or checkpoint") as e:
        make_predictor("m", str(tmp_path / "nope"))
    assert str(tmp_path / "nope") in str(e.value)
    (tmp_path / "manifest.json").write_text("{}")
    with pytest.raises(FileFormatError, match="not a model package folder"):
        make_predictor("m", str(tmp_path / "manifest.json"))
    with pytest.raises(InputError, match="a model must be"):  # a word, not a path: the choices
        make_predictor("m", "lbs-nope")

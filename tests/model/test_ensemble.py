"""An ensemble of trained networks: the mean of its members, saved, loaded, trained never, exported like one."""

import json

import numpy as np
import pytest
import torch

from segadeform.errors import FileFormatError, InputError
from segadeform.export.package import graph_specs, sample_inputs
from segadeform.model import ModelConfig, SEGANet, load_checkpoint, save_checkpoint
from segadeform.model.ensemble import SEGAEnsemble, build_model, combine


def trained(seed, cfg=None):
    """A network as after training: its own weights and the residual corrections switched on."""
    torch.manual_seed(seed)
    net = SEGANet(cfg or ModelConfig(hidden=16, lstm_hidden=16)).eval()
    with torch.no_grad():
        net.weight_gate.fill_(0.6 + 0.1 * seed)
        net.blend_gate.fill_(0.4 + 0.1 * seed)
    return net


def inputs(cfg, n=33, k=5, b=4):
    enc = sample_inputs(cfg, "garment_encoder", n=n, k=k, b=1)
    dec = sample_inputs(cfg, "deformer", n=n, k=k, b=b)
    return {k_: torch.as_tensor(v) for k_, v in {**enc, **dec}.items()}


def run(net, t):
    with torch.no_grad():
        g = net.garment_encoder(t["features"], t["nbr"], t["mask"], t["descriptor"])
        out = net.deformer(
            g[0], t["window"], t["betas"], t["rest"], t["nbr"], t["mask"], t["joints"], t["trans"], t["log_wbody"]
        )
    return g, out


def test_an_ensemble_is_its_members_side_by_side_and_the_mean_of_their_outputs():
    nets = [trained(s) for s in range(3)]
    ens = combine(nets)
    assert isinstance(ens, SEGAEnsemble) and ens.cfg.ensemble == 3 and ens.residual
    t = inputs(nets[0].cfg)
    g, (v, w, b) = run(ens, t)
    assert g.shape == (1, 33, 3 * 24)
    outs = [run(n, t) for n in nets]
    for i, (gi, _) in enumerate(outs):
        torch.testing.assert_close(g[..., 24 * i : 24 * (i + 1)], gi, rtol=0, atol=0)
    for got, j in ((v, 0), (w, 1), (b, 2)):
        want = torch.stack([o[1][j] for o in outs]).mean(0)
        torch.testing.assert_close(got, want, rtol=0, atol=1e-6)
    # the members differ (else the mean proves nothing), and the weights stay a partition of unity
    assert (outs[0][1][0] - outs[1][1][0]).abs().max() > 1e-3
    assert (w >= 0).all() and torch.allclose(w.sum(-1), torch.ones(4, 33), atol=1e-6)
    # an ensemble of ensembles is flat
    again = combine([combine(nets[:2]), nets[2]])
    assert again.cfg.ensemble == 3
    torch.testing.assert_close(run(again, t)[1][0], v, rtol=0, atol=0)


def test_an_ensemble_checkpoint_round_trips(tmp_path):
    ens = combine([trained(0), trained(1)])
    save_checkpoint(tmp_path / "e.pt", ens)
    back = load_checkpoint(tmp_path / "e.pt").eval()
    assert isinstance(back, SEGAEnsemble) and back.cfg == ens.cfg
    t = inputs(ens.cfg)
    torch.testing.assert_close(run(back, t)[1][0], run(ens, t)[1][0], rtol=0, atol=0)
    assert isinstance(build_model(ModelConfig()), SEGANet)


def test_what_an_ensemble_refuses(tmp_path):
    with pytest.raises(InputError, match="two or more"):
        combine([trained(0)])
    with pytest.raises(InputError, match=r"network 1 \(from 0.*differs.*hidden: 16 vs 8"):
        combine([trained(0), trained(1, ModelConfig(hidden=8, heads=4, lstm_hidden=16))])
    with pytest.raises(InputError, match="motion-history"):
        SEGAEnsemble(ModelConfig(history=4, ensemble=2))
    with pytest.raises(InputError, match="one SEGANet is one network"):
        SEGANet(ModelConfig(ensemble=2))
    with pytest.raises(InputError, match="ensemble must be a positive integer"):
        ModelConfig(ensemble=0)
    ens = combine([trained(0), trained(1)])
    t = inputs(ens.cfg)
    with pytest.raises(InputError, match=r"expected \(N, 48\)"):
        ens.deformer(t["log_wbody"], t["window"], t["betas"], t["rest"], t["nbr"], t["mask"], t["joints"], t["trans"])
    # a training config cannot ask for one
    from segadeform.train.config import load_train_config

    (tmp_path / "t.toml").write_text('[data]\ndataset = "d"\n[model]\nensemble = 2\n')
    with pytest.raises(FileFormatError, match="a run trains one network"):
        load_train_config(tmp_path / "t.toml")


def test_every_effect_variant_of_an_ensemble_is_the_mean_of_its_members_variants():
    """The per-effect deformers an export writes (skinning x wrinkles x dynamics) are built from the ensemble's
    weights as they are from one network's: each is the mean of its members' same variant.  (Exporting them all to
    ONNX is the single network's path, which ``tests/export`` runs on every variant; an ensemble's export of all
    eight cost 3-4 minutes of the suite.)"""
    from segadeform.export.package import _variant_model, deformer_variants

    nets = [trained(0), trained(1)]
    ens = combine(nets).freeze()
    variants = deformer_variants(ens.cfg)
    assert len(variants) == 8
    for name, var in variants.items():
        vcfg = var["config"]
        t = inputs(vcfg)
        got = run(_variant_model(ens, vcfg), t)[1]
        outs = [run(_variant_model(n.freeze(), vcfg.replace(ensemble=1)), t)[1] for n in nets]
        for j, x in enumerate(got):
            if x is None:
                assert all(o[j] is None for o in outs), name
                continue
            torch.testing.assert_close(x, torch.stack([o[j] for o in outs]).mean(0), rtol=0, atol=1e-6, msg=name)


def test_an_exported_ensemble_matches_torch_and_runs_in_the_python_runtime(ensemble_model):
    """The runtime's package runs the ensemble's encoder and deformer with the single network's interface (the code
    only wider), as torch does.  The package is conftest's ensemble_model (two DQS networks), which tests/runtimes
    also runs in Node, C++ and the browser."""
    from segadeform.runtime.package import ModelPackage

    ens, path, members = ensemble_model
    m = json.loads((path / "manifest.json").read_text())
    assert m["config"]["ensemble"] == 2
    one = ModelConfig.from_dict({**m["config"], "ensemble": 1})
    width = graph_specs(one)["garment_encoder"]["outputs"][0]["shape"][-1]
    assert m["graphs"]["garment_encoder"]["outputs"][0]["shape"] == ["B", "N", 2 * width]
    assert [g for g in m["graphs"] if g.startswith("deformer_")] == [ens_default_deformer(ens)]
    pkg = ModelPackage(path)
    t = inputs(ens.cfg)
    f32 = {k: v.numpy() for k, v in t.items()}
    (g,) = pkg.run("garment_encoder", {k: f32[k] for k in ("features", "nbr", "mask", "descriptor")})
    dec = pkg.default_deformer
    names = [i["name"] for i in pkg.spec(dec)["inputs"]]
    v = pkg.run(dec, {k: (g[0] if k == "g" else f32[k]) for k in names})[0]
    g_t, (v_t, _, _) = run(ens, t)
    np.testing.assert_allclose(g, g_t.numpy(), rtol=1e-4, atol=1e-5)
    np.testing.assert_allclose(v, v_t.numpy(), rtol=1e-4, atol=1e-5)
    # and the mean of its members' outputs
    outs = [run(n.freeze(), t)[1][0] for n in members]
    np.testing.assert_allclose(v, torch.stack(outs).mean(0).numpy(), rtol=1e-4, atol=1e-5)


def ens_default_deformer(ens):
    from segadeform.contracts import model_package as contract

    return contract.deformer_name(contract.default_effects(ens.cfg))


def test_the_ensemble_command_writes_one_checkpoint_and_never_over_a_file_it_did_not_write(tmp_path, capsys):
    from segadeform.cli.main import main
    from segadeform.model.network import checkpoint_training_garments

    desc = [[0.1 * i for i in range(32)], [0.2 * i for i in range(32)]]
    save_checkpoint(
        tmp_path / "a.pt", trained(0), training_garments={"names": ["skirt"], "descriptors": desc[:1], "openings": [2]}
    )
    save_checkpoint(
        tmp_path / "b.pt",
        trained(1),
        training_garments={"names": ["skirt", "dress"], "descriptors": desc, "openings": [2, 2]},
    )
    assert main(["ensemble", str(tmp_path / "a.pt"), str(tmp_path / "b.pt"), "-o", str(tmp_path / "e.pt")]) == 0
    assert "2 networks averaged" in capsys.readouterr().out
    e = load_checkpoint(tmp_path / "e.pt")
    assert isinstance(e, SEGAEnsemble) and e.cfg.ensemble == 2
    names, descs, openings = checkpoint_training_garments(tmp_path / "e.pt")
    assert names == ["skirt", "dress"] and openings == [2, 2] and np.allclose(descs, desc)
    # run again: it replaces its own output; a file it did not write stays as it was
    assert main(["ensemble", str(tmp_path / "a.pt"), str(tmp_path / "b.pt"), "-o", str(tmp_path / "e.pt")]) == 0
    (tmp_path / "mine.pt").write_bytes(b"user data")
    assert main(["ensemble", str(tmp_path / "a.pt"), str(tmp_path / "b.pt"), "-o", str(tmp_path / "mine.pt")]) == 1
    assert (tmp_path / "mine.pt").read_bytes() == b"user data"
    # one network, or networks of different configurations: one line, exit 1, nothing written
    save_checkpoint(tmp_path / "c.pt", trained(2, ModelConfig(hidden=8, lstm_hidden=16)))
    capsys.readouterr()
    for args, says in (
        (["a.pt"], "two or more"),
        (["a.pt", "c.pt"], "c.pt: its network's configuration differs from"),
        (["e.pt", "c.pt"], "c.pt: its network's configuration differs from"),  # an ensemble and one network
        (["a.pt", "a.pt"], "a.pt: a checkpoint given twice"),
    ):
        out = tmp_path / "x.pt"
        assert main(["ensemble", *(str(tmp_path / a) for a in args), "-o", str(out)]) == 1
        assert not out.exists()
        assert says in capsys.readouterr().err
    # an ensemble and another network make one flat ensemble
    assert main(["ensemble", str(tmp_path / "e.pt"), str(tmp_path / "a.pt"), "-o", str(tmp_path / "f.pt")]) == 0
    assert load_checkpoint(tmp_path / "f.pt").cfg.ensemble == 3


def test_an_ensemble_records_its_members_body_and_refuses_members_of_two_bodies(tmp_path, capsys):
    """The body each member was trained on (model.pt's ``body``): the ensemble records it when every member records
    the same one, refuses members trained on two bodies, and records none when a member does not say."""
    from segadeform.cli.main import main
    from segadeform.model.network import checkpoint_body

    one, two = {"name": "a.npz", "sha256": "1" * 64}, {"name": "b.npz", "sha256": "2" * 64}
    for name, seed, body in (("a", 0, one), ("b", 1, one), ("c", 2, two)):
        save_checkpoint(tmp_path / f"{name}.pt", trained(seed), body=body)
    save_checkpoint(tmp_path / "old.pt", trained(3))
    ens = lambda *names: ["ensemble", *(str(tmp_path / f"{n}.pt") for n in names[:-1]), "-o", str(tmp_path / names[-1])]  # noqa: E731
    assert main(ens("a", "b", "ab.pt")) == 0 and checkpoint_body(tmp_path / "ab.pt") == one
    assert main(ens("a", "old", "ao.pt")) == 0 and checkpoint_body(tmp_path / "ao.pt") is None
    capsys.readouterr()
    assert main(ens("a", "old", "c", "x.pt")) == 1 and not (tmp_path / "x.pt").exists()
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "c.pt: it was trained on another body than " in err, err
    assert "(expected a.npz (sha256 111111111111), got b.npz (sha256 222222222222))" in err, err

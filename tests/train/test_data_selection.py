"""[data] exclude / fraction: which samples a training run sees."""

import pytest

from segadeform.errors import FileFormatError
from segadeform.train.config import load_train_config


def _cfg(tmp_path, text):
    p = tmp_path / "t.toml"
    p.write_text(text)
    return load_train_config(p, dataset=tmp_path)


def test_exclude_globs_and_nested_fractions(tmp_path):
    ids = [f"g{i}__b0__cmu-{i}" for i in range(20)] + [f"g{i}__b0__walk-s{i}" for i in range(20)]
    assert _cfg(tmp_path, "").select(ids) == ids
    no_mocap = _cfg(tmp_path, '[data]\nexclude = ["*__cmu-*"]\n').select(ids)
    assert no_mocap == [i for i in ids if "cmu" not in i]
    quarter = _cfg(tmp_path, "[data]\nfraction = 0.25\n").select(ids)
    half = _cfg(tmp_path, "[data]\nfraction = 0.5\n").select(ids)
    assert len(quarter) == 10 and len(half) == 20 and set(quarter) <= set(half)  # 1x within 2x within 4x
    assert quarter == _cfg(tmp_path, "[data]\nfraction = 0.25\n").select(list(reversed(ids)))  # order-free


@pytest.mark.parametrize(
    "text, msg",
    [
        ("[data]\nfraction = 0\n", "fraction"),
        ("[data]\nfraction = 1.5\n", "fraction"),
        ('[data]\nexclude = "cmu"\n', "exclude"),
        ("[data]\nsplits = 1\n", "unknown"),
        ('[data]\nmirror = "yes"\n', "mirror"),
    ],
)
def test_bad_selections_are_refused(tmp_path, text, msg):
    with pytest.raises(FileFormatError, match=msg):
        _cfg(tmp_path, text)


def test_a_config_changes_its_base(tmp_path):
    """``base = "full.toml"``: the base's tables with the config's keys over them; the base's relative paths
    stay the base's; a cycle is refused."""
    import pytest

    from segadeform.errors import FileFormatError
    from segadeform.train import load_train_config

    (tmp_path / "sub").mkdir()
    (tmp_path / "sub" / "full.toml").write_text(
        "[data]\ndataset = 'data'\nval_split = 'val'\n[model]\nhidden = 16\n[optim]\nsteps = 5\nseed = 0\nlr = 0.002\n"
    )
    (tmp_path / "seed1.toml").write_text("base = 'sub/full.toml'\n[optim]\nseed = 1\n")
    full = load_train_config(tmp_path / "sub" / "full.toml")
    one = load_train_config(tmp_path / "seed1.toml")
    assert one.optim.seed == 1 and one.optim.steps == 5 and one.optim.lr == 0.002 and one.model.hidden == 16
    assert one.dataset == full.dataset == ((tmp_path / "sub" / "data").resolve(),) and one.val_split == "val"
    assert one.digest() != full.digest()
    (tmp_path / "a.toml").write_text("base = 'b.toml'\n")
    (tmp_path / "b.toml").write_text("base = 'a.toml'\n")
    with pytest.raises(FileFormatError, match="each other"):
        load_train_config(tmp_path / "a.toml")
    # a base that is not there: the config that names it is named (the error named the missing base alone)
    (tmp_path / "c.toml").write_text("base = 'nope.toml'\n")
    with pytest.raises(FileFormatError, match="base names no training config") as e:
        load_train_config(tmp_path / "c.toml")
    assert str(e.value).startswith(str(tmp_path / "c.toml")) and "nope.toml" in str(e.value)


def test_the_shipped_recipe_reads_the_local_dataset_and_the_durable_store_where_they_are(tmp_path, capsys):
    """A fresh checkout beside ../shared/data/sim trains with the shipped configs as they are: neither the local
    dataset folder nor the store is required, both are read where they exist; with neither, a run says where it
    looked and leaves no output behind."""
    from segadeform.cli.main import main
    from tests.conftest import SAMPLES

    root = SAMPLES.parent
    for name in ("full.toml", "gpu.toml", "plaingat_seed1.toml"):
        cfg = load_train_config(SAMPLES / "train" / "continuum" / name)
        assert cfg.dataset == ()
        assert cfg.optional == (
            (root / "data" / "continuum").resolve(),
            (root.parent / "shared" / "data" / "sim").resolve(),
        )
    # roots given on the command line are the data: the config's own are not read beside them
    given = load_train_config(SAMPLES / "train" / "continuum" / "full.toml", dataset=tmp_path)
    assert given.dataset == (tmp_path,) and given.optional == ()
    text = (SAMPLES / "train" / "continuum" / "full.toml").read_text()
    nowhere = f'optional = ["{tmp_path / "no-data"}", "{tmp_path / "no-store"}"]'
    cfg = tmp_path / "cfg" / "full.toml"
    cfg.parent.mkdir()
    cfg.write_text(
        text.replace('optional = ["../../../data/continuum", "../../../../shared/data/sim"]', nowhere).replace(
            '"../../datasets/continuum.toml"', f'"{SAMPLES / "datasets" / "continuum.toml"}"'
        )
    )
    out = tmp_path / "run"
    assert main(["train", str(cfg), "-o", str(out), "--steps", "1", "--threads", "1"]) == 1
    err = capsys.readouterr().err
    assert "no-data is not there" in err and "no-store is not there" in err and len(err.strip().splitlines()) == 1
    assert not out.exists()
    # a folder of the user's own: the failed run leaves it as it was, with and without --force
    out.mkdir()
    (out / "mine.txt").write_text("mine")
    for extra in ([], ["--force"]):
        assert main(["train", str(cfg), "-o", str(out), "--steps", "1", "--threads", "1", *extra]) == 1
        capsys.readouterr()
        assert sorted(p.name for p in out.iterdir()) == ["mine.txt"] and (out / "mine.txt").read_text() == "mine"

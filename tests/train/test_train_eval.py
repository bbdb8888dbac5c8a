"""Training runs, logs, resumes deterministically; evaluation computes the paper's metrics."""

from __future__ import annotations

import csv
import json
from types import SimpleNamespace

import numpy as np
import pytest

torch = pytest.importorskip("torch")

from segadeform.cli.main import main  # noqa: E402
from segadeform.runtime.predictor import PackagePredictor  # noqa: E402
from segadeform.train import load_train_config  # noqa: E402
from segadeform.train.evaluate import evaluate  # noqa: E402
from segadeform.train.metrics import METRICS  # noqa: E402
from segadeform.train.predictors import make_predictors  # noqa: E402
from segadeform.train.trainer import train  # noqa: E402

from ..conftest import SAMPLES  # noqa: E402

SHIPPED = SAMPLES / "models" / "default"


def test_train_writes_run_folder(synthetic_dataset, tiny_config, tmp_path, body, caplog):
    cfg = load_train_config(tiny_config, dataset=synthetic_dataset)
    run = tmp_path / "run"
    with caplog.at_level("WARNING", logger="segadeform.train.trainer"):
        final = train(cfg, run, body, log_every=2, val_ids=["skirt__b0__swing"])
    # a test-split sample given to choose the model is said (a user's trial: it went unsaid)
    assert any("1 of the 1 samples that choose the model are of the test split" in r.message for r in caplog.records)
    rows = list(csv.DictReader(open(run / "loss.csv")))
    assert [int(r["step"]) for r in rows] == [2, 4, 6]
    assert all(np.isfinite(float(r["total"])) for r in rows) and rows[-1]["val_vertex"] != ""
    info = json.loads((run / "train.json").read_text())
    assert info["steps"] == 6 and info["hardware"]["device"] == "cpu" and info["train_seconds"] > 0
    assert sorted(info["samples"]) == ["shorts__b0__walk", "skirt__b0__walk"]  # the test split stays out
    assert (run / "loss.png").stat().st_size > 1000 and final.is_file() and (run / "config.toml").is_file()
    # the checkpoint names the garments it saw (export puts them in the manifest; runtimes warn about others)
    from segadeform.model.network import checkpoint_training_garments

    names, desc, openings = checkpoint_training_garments(final)
    assert sorted(names) == ["shorts", "skirt"] and desc.shape == (2, cfg.model.n_star) and sorted(openings) == [2, 3]


def test_resume_continues_the_same_run(synthetic_dataset, tiny_config, tmp_path, body):
    cfg = load_train_config(tiny_config, dataset=synthetic_dataset)
    a = train(cfg, tmp_path / "a", body, log_every=3)

    def stop(step, row):
        if step == 3:
            raise KeyboardInterrupt  # killed right after the step-3 checkpoint

    with pytest.raises(KeyboardInterrupt):
        train(cfg, tmp_path / "b", body, log_every=3, progress=stop)
    assert not (tmp_path / "b" / "model.pt").exists()
    b = train(cfg, tmp_path / "b", body, log_every=3)
    sa, sb = torch.load(a, weights_only=True)["state_dict"], torch.load(b, weights_only=True)["state_dict"]
    assert max(float((sa[k].float() - sb[k].float()).abs().max()) for k in sa) < 1e-6
    steps = [int(r["step"]) for r in csv.DictReader(open(tmp_path / "b" / "loss.csv"))]
    assert steps == [3, 6]


def test_an_interrupted_train_says_the_same_command_resumes_it_and_the_resumed_run_says_from_where(
    synthetic_dataset, tiny_config, tmp_path, capsys, monkeypatch
):
    """Ctrl-C during `train` printed "Aborted!" alone, and a resumed run did not say it resumed (a user's trial)."""
    import segadeform.train.trainer as trainer_mod

    steps = [0]
    fast = trainer_mod.step_losses

    def stopped(*a, **k):
        if "prior_scale" in k:  # a training step
            steps[0] += 1
            if steps[0] == 5:  # the step after the step-3 checkpoint's next one
                raise KeyboardInterrupt
        return fast(*a, **k)

    run = tmp_path / "run"
    args = ["train", str(tiny_config), "--dataset", str(synthetic_dataset), "-o", str(run)]
    monkeypatch.setattr(trainer_mod, "step_losses", stopped)
    assert main(args) == 1
    err = capsys.readouterr().err
    assert err == (
        f"Error: interrupted: run the same command again to resume from step 3 (the checkpoint {run / 'last.pt'})\n"
    )
    assert main(args) == 0
    captured = capsys.readouterr()
    assert captured.err.startswith(f"resuming at step 3/6 from {run / 'last.pt'}\n"), captured.err
    assert "trained 6 steps" in captured.out
    assert main(args) == 0 and "resuming" not in capsys.readouterr().err  # a finished run: nothing resumed


def test_a_run_resumed_between_two_logged_steps_logs_the_rows_of_one_run(
    synthetic_dataset, tiny_config, tmp_path, body
):
    """Checkpoints every 3 steps, rows every 2: stopped at step 4, the run resumes from step 3, and its row 4 averaged
    step 4 alone where one run's averages steps 3 and 4 (a user's trial: checkpoint 125, rows every 10).  The
    checkpoint keeps the rows' running sums."""
    cfg = load_train_config(tiny_config, dataset=synthetic_dataset)
    train(cfg, tmp_path / "a", body, log_every=2)

    def stop(step, row):
        if step == 4:
            raise KeyboardInterrupt  # after the step-3 checkpoint, at the step-4 row

    with pytest.raises(KeyboardInterrupt):
        train(cfg, tmp_path / "b", body, log_every=2, progress=stop)
    assert torch.load(tmp_path / "b" / "last.pt", weights_only=False)["step"] == 3
    train(cfg, tmp_path / "b", body, log_every=2)
    ra, rb = (list(csv.DictReader(open(tmp_path / r / "loss.csv"))) for r in ("a", "b"))
    assert [r["step"] for r in ra] == [r["step"] for r in rb] == ["2", "4", "6"]
    for x, y in zip(ra, rb, strict=True):
        assert abs(float(x["total"]) - float(y["total"])) <= 1e-6 * max(1.0, abs(float(x["total"]))), (x, y)


def test_resume_refuses_another_config(synthetic_dataset, tiny_config, tmp_path, body):
    from segadeform.errors import InputError

    cfg = load_train_config(tiny_config, dataset=synthetic_dataset, overrides={"optim.steps": 3})
    train(cfg, tmp_path / "r", body)
    other = load_train_config(tiny_config, dataset=synthetic_dataset, overrides={"optim.lr": 0.1})
    # what changed is named (a user's trial: the same config.toml, the error blamed it; --seconds differed)
    with pytest.raises(InputError, match=r"different config.*: optim\.lr \S+ -> 0\.1, optim\.steps 3 -> "):
        train(other, tmp_path / "r", body)


def test_a_split_the_dataset_lacks_names_the_config_and_the_splits_and_writes_nothing(
    synthetic_dataset, tiny_config, tmp_path, body
):
    """`split = "trian"` said "no 'trian' samples (expected segadeform dataset make first, got Pack(...))" and left
    the run's folder (a user's trial)."""
    from segadeform.errors import InputError

    cfg = load_train_config(tiny_config, dataset=synthetic_dataset, overrides={"data.split": "trian", "optim.steps": 3})
    with pytest.raises(
        InputError, match=r"no 'trian' samples in the dataset \(expected data.split = test \| train"
    ) as e:
        train(cfg, tmp_path / "r", body)
    assert str(tiny_config) in str(e.value) and "Pack(" not in str(e.value)
    assert not (tmp_path / "r").exists()


def test_an_empty_dataset_folder_is_said_to_hold_no_samples(tiny_config, tmp_path, body):
    """`--dataset empty` (a folder with nothing in it) said "got no dataset root: none given" (a user's trial)."""
    from segadeform.errors import InputError

    (tmp_path / "empty").mkdir()
    cfg = load_train_config(tiny_config, dataset=tmp_path / "empty", overrides={"optim.steps": 1})
    with pytest.raises(
        InputError, match=r"no 'train' samples in the dataset \(expected segadeform dataset make first, "
    ):
        train(cfg, tmp_path / "r", body)
    with pytest.raises(InputError, match=rf"got {tmp_path / 'empty'}, an empty folder: no samples\)$"):
        train(cfg, tmp_path / "r", body)
    assert not (tmp_path / "r").exists()


def test_what_a_run_leaves_that_is_not_a_model_is_named_in_one_line(synthetic_dataset, tiny_config, tmp_path, body):
    """A researcher's trial: a run's best.pt was refused as "must hold 'config'" after the last.pt message had
    pointed at it; weights that do not fit their config printed torch's 42 lines; optim.checkpoint_every = 0 was a
    modulo by zero after files were written; a validation split with no samples went unsaid."""
    import logging

    import torch

    from segadeform.errors import FileFormatError, InputError
    from segadeform.model.network import load_checkpoint

    run = tmp_path / "r"
    cfg = load_train_config(tiny_config, dataset=synthetic_dataset, overrides={"optim.steps": 2})
    train(cfg, run, body)
    ck = torch.load(run / "model.pt", weights_only=True)
    if not (run / "best.pt").is_file():  # what the trainer writes there when a validation split chooses
        torch.save({"state_dict": ck["state_dict"], "step": 1, "val_vertex": 0.01}, run / "best.pt")
    for name, words in (("best.pt", "best checkpoint so far"), ("last.pt", "resume state")):
        with pytest.raises(FileFormatError, match=words) as e:
            load_checkpoint(run / name)
        assert "\n" not in str(e.value) and "or best.pt" not in str(e.value)
    ck["config"] = dict(ck["config"], hidden=2 * ck["config"]["hidden"])
    torch.save(ck, tmp_path / "mix.pt")
    with pytest.raises(FileFormatError, match=r"weights do not fit its config \(size mismatch for .*; \d+ more\)") as e:
        load_checkpoint(tmp_path / "mix.pt")
    assert "\n" not in str(e.value)
    with pytest.raises(InputError, match=r"optim.checkpoint_every must be an integer >= 1"):
        load_train_config(tiny_config, dataset=synthetic_dataset, overrides={"optim.checkpoint_every": 0})
    # a validation split no dataset makes (a typo) is refused before anything is written (it trained unvalidated,
    # with a warning: a researcher's trial)
    typo = load_train_config(
        tiny_config, dataset=synthetic_dataset, overrides={"optim.steps": 1, "data.val_split": "vall"}
    )
    with pytest.raises(InputError, match="no 'vall' samples in the dataset, and no dataset makes such a split"):
        train(typo, tmp_path / "typo", body)
    assert not (tmp_path / "typo").exists()
    # one a dataset makes but this one lacks: said (model.pt is then the last step)
    quiet = load_train_config(
        tiny_config, dataset=synthetic_dataset, overrides={"optim.steps": 1, "data.val_split": "test-garment"}
    )
    records = []
    handler = logging.Handler()
    handler.emit = records.append
    logging.getLogger("segadeform.train.trainer").addHandler(handler)
    try:
        train(quiet, tmp_path / "q", body)
    finally:
        logging.getLogger("segadeform.train.trainer").removeHandler(handler)
    assert any("no 'test-garment' samples" in r.getMessage() for r in records)


def test_resume_refuses_other_samples(synthetic_dataset, tiny_config, tmp_path, body):
    """A run trained on two datasets, run again on one of them, said it had trained and rewrote train.json to name
    the one dataset while model.pt kept the first run's weights (a user's trial): the samples are the run's too."""
    import shutil

    from segadeform.errors import InputError

    fewer = tmp_path / "fewer"
    shutil.copytree(synthetic_dataset, fewer)
    for p in (fewer / "samples").glob("shorts__b0__walk.*"):
        p.unlink()  # a copy with one training sample less
    cfg = load_train_config(tiny_config, dataset=synthetic_dataset, overrides={"optim.steps": 3})
    run = tmp_path / "r"
    train(cfg, run, body)
    before = {p.name: p.read_bytes() for p in run.iterdir() if p.is_file()}
    with pytest.raises(InputError, match="trained on other samples") as e:
        train(load_train_config(tiny_config, dataset=fewer, overrides={"optim.steps": 3}), run, body)
    assert "1 training and 0 validation samples now" in str(e.value)
    assert {p.name: p.read_bytes() for p in run.iterdir() if p.is_file()} == before  # train.json, model.pt as they were
    train(cfg, run, body)  # the run's own samples: nothing to do, and no refusal


def test_a_model_records_its_body_and_eval_export_and_resume_refuse_another(
    synthetic_dataset, tiny_config, tmp_path, body, capsys, monkeypatch
):
    """A model trained on a second body was evaluated on the first's data, exported with the first's body graphs
    and resumed on the first without a word (a user's trial): model.pt, last.pt and train.json record the body,
    and each of them refuses another in one line naming both; a checkpoint that records none keeps the old way."""
    import dataclasses

    from segadeform.body import load_body
    from segadeform.body.identity import body_label
    from segadeform.errors import InputError
    from segadeform.model.network import checkpoint_body

    other_path = tmp_path / "tall.npz"
    dataclasses.replace(body, v_template=body.v_template * 1.01).save(other_path)
    tall = load_body(other_path)
    run = tmp_path / "r"
    cfg = load_train_config(tiny_config, dataset=synthetic_dataset, overrides={"optim.steps": 2})
    final = train(cfg, run, tall)
    label = body_label(tall)
    assert label["name"] == "tall.npz" and label["sha256"] != body_label(body)["sha256"]
    assert checkpoint_body(final) == label and json.loads((run / "train.json").read_text())["body"] == label
    assert torch.load(run / "last.pt", weights_only=False)["body"] == label
    both = rf"expected default_body.npz \(sha256 {body_label(body)['sha256'][:12]}\), got tall.npz \(sha256 "
    with pytest.raises(InputError, match=r"model tall was trained on another body than the dataset's.*" + both):
        evaluate(synthetic_dataset, body, make_predictors({"tall": str(final)}))
    with pytest.raises(InputError, match="model pkg was trained on another body"):  # a package: its body graphs'
        evaluate(synthetic_dataset, tall, make_predictors({"pkg": str(SHIPPED)}, package=PackagePredictor))
    assert main(["eval", str(synthetic_dataset), "-m", f"tall={final}", "-o", str(tmp_path / "ev")]) == 1
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "tall.npz" in err and "default_body.npz" in err, err
    assert not (tmp_path / "ev").exists()
    with pytest.raises(InputError, match=r"a run trained on another body .*expected tall.npz .*got default_body.npz"):
        train(cfg, run, body)
    # export: the shipped body (its default) and another --body are refused; the checkpoint's own body is exported
    exported = []

    class Exported(Exception):
        pass

    def export_package(model, out, **kw):  # the body it would export, without the minutes an export takes
        exported.append(kw["body"])
        records.append(kw["extra_manifest"].get("training_body"))
        raise Exported

    records = []  # the manifest's record of the training body, which export-body --force leaves as it is

    monkeypatch.setattr("segadeform.export.export_package", export_package)
    for extra, words in (([], "than the shipped one"), (["--body", str(body.path)], "than --body's")):
        assert main(["export", str(final), "-o", str(tmp_path / "pkg"), *extra]) == 1
        err = capsys.readouterr().err
        assert err.count("\n") == 1 and words in err and "expected tall.npz" in err and "default_body.npz" in err, err
    assert not exported and not (tmp_path / "pkg").exists()
    with pytest.raises(Exported):
        main(["export", str(final), "-o", str(tmp_path / "pkg"), "--body", str(other_path)])
    assert [body_label(b) for b in exported] == [label] and records == [label]
    # a checkpoint written before bodies were recorded: taken on any body, as before
    old = torch.load(final, weights_only=True)
    del old["body"]
    torch.save(old, tmp_path / "old.pt")
    assert checkpoint_body(tmp_path / "old.pt") is None
    with pytest.raises(Exported):
        main(["export", str(tmp_path / "old.pt"), "-o", str(tmp_path / "pkg2")])
    assert body_label(exported[-1]) == body_label(body) and records[-1] is None
    evaluate(synthetic_dataset, body, make_predictors({"old": str(tmp_path / "old.pt")}))


def test_resume_refuses_other_dataset_roots_holding_the_same_samples(synthetic_dataset, tiny_config, tmp_path, body):
    """A run resumed with other --dataset roots holding samples of the same names was taken, and train.json then
    named the new roots alone, though the refusals say a run resumes with "--dataset as it was then" (a user's
    trial): the roots are the run's too, shown both ways; the same roots by another path resume."""
    import os
    import shutil

    from segadeform.errors import InputError

    copy = tmp_path / "copy"
    shutil.copytree(synthetic_dataset, copy)
    cfg = load_train_config(tiny_config, dataset=synthetic_dataset, overrides={"optim.steps": 2})
    run = tmp_path / "r"
    train(cfg, run, body)
    before = {p.name: p.read_bytes() for p in run.iterdir() if p.is_file()}
    with pytest.raises(InputError, match="trained on other dataset roots") as e:
        train(load_train_config(tiny_config, dataset=copy, overrides={"optim.steps": 2}), run, body)
    assert f"(expected {synthetic_dataset.resolve()} (the run's), or a new -o folder, got {copy})" in str(e.value)
    assert {p.name: p.read_bytes() for p in run.iterdir() if p.is_file()} == before
    rel = os.path.relpath(synthetic_dataset)
    train(load_train_config(tiny_config, dataset=rel, overrides={"optim.steps": 2}), run, body)  # the same root


def test_training_lowers_the_error(synthetic_dataset, tmp_path, body):
    """Free (paper) weights start far off and learn; residual weights start at the body's LBS, which is
    what the synthetic samples are, so their first logged error is already small."""
    p = tmp_path / "c.toml"
    p.write_text(
        '[model]\nhidden = 16\nlstm_hidden = 16\nweights = "free"\n[optim]\nsteps = 40\nframes = 4\nlr = 0.003\n'
    )
    cfg = load_train_config(p, dataset=synthetic_dataset)
    train(cfg, tmp_path / "run", body, log_every=5)
    rows = list(csv.DictReader(open(tmp_path / "run" / "loss.csv")))
    assert float(rows[-1]["vertex"]) < 0.7 * float(rows[0]["vertex"])
    p.write_text("[model]\nhidden = 16\nlstm_hidden = 16\n[optim]\nsteps = 5\nframes = 4\nlr = 0.003\n")
    train(load_train_config(p, dataset=synthetic_dataset), tmp_path / "res", body, log_every=5)
    res = list(csv.DictReader(open(tmp_path / "res" / "loss.csv")))
    assert float(res[0]["vertex"]) < 0.2 * float(rows[0]["vertex"])


def test_evaluate_lbs_is_exact_on_skinned_data_and_models_are_measured(synthetic_dataset, tiny_config, tmp_path, body):
    cfg = load_train_config(tiny_config, dataset=synthetic_dataset)
    ck = train(cfg, tmp_path / "run", body)
    res = evaluate(
        synthetic_dataset,
        body,
        make_predictors({"lbs": "lbs", "sega": str(ck)}, package=PackagePredictor),
        push_out_margin=0.004,
    )
    assert res["samples"] == ["skirt__b0__swing"] and set(res["models"]) == {"lbs", "sega", "sega + push-out"}
    lbs = res["models"]["lbs"]
    assert lbs["vertex_cm"] < 1e-3 and lbs["low_cm"] < 1e-3 and lbs["jitter_mm"] < 1e-3
    sega = res["models"]["sega"]
    assert all(np.isfinite(sega[k]) for k in METRICS) and sega["vertex_cm"] > lbs["vertex_cm"]
    assert res["models"]["sega + push-out"]["penetration_pct"] <= sega["penetration_pct"]
    assert set(res["by_type"]["sega"]) == {"skirt"} and len(res["per_frame"]["sega"]) == 12
    # a split the dataset does not have: the ones it has are named (a user's `test-motion` split went unsaid)
    from segadeform.errors import InputError

    with pytest.raises(InputError, match=r"no 'val' samples in the dataset \(expected --split test \| train"):
        evaluate(synthetic_dataset, body, make_predictors({"lbs": "lbs"}), split="val")


def test_cli_train_and_eval(synthetic_dataset, tiny_config, tmp_path, capsys):
    run = tmp_path / "run"
    assert main(["train", str(tiny_config), "--dataset", str(synthetic_dataset), "-o", str(run), "--steps", "2"]) == 0
    out = capsys.readouterr().out
    assert "trained 2 steps" in out and "model.pt is step" not in out  # no validation split: the last step
    # with one, the last line says which step model.pt is, and when it is the untrained network (a user's trial got
    # step 0 unsaid)
    val_cfg = tmp_path / "val.toml"
    val_cfg.write_text(tiny_config.read_text() + "[data]\nval_split = 'test'\n")
    run_v = tmp_path / "run_v"
    assert main(["train", str(val_cfg), "--dataset", str(synthetic_dataset), "-o", str(run_v), "--steps", "3"]) == 0
    last = capsys.readouterr().out.strip().splitlines()[-1]
    chosen = json.loads((run_v / "train.json").read_text())["chosen"]
    assert last.startswith(f"model.pt is step {chosen['step']}: the lowest 'test' vertex error, ")
    assert ("the untrained network" in last) == (chosen["step"] == 0)
    # the same command again: said to be done, not trained again (a user's trial read "trained 2 steps" as new)
    assert main(["train", str(tiny_config), "--dataset", str(synthetic_dataset), "-o", str(run), "--steps", "2"]) == 0
    assert "already trained: 2 steps" in capsys.readouterr().out
    # ... and nothing rewritten: the record's time is the run's (it read 0 s once), loss.csv's last row agrees
    info = json.loads((run / "train.json").read_text())
    last = list(csv.DictReader(open(run / "loss.csv")))[-1]
    assert abs(info["train_seconds"] - float(last["seconds"])) <= 0.06  # (one rounded to 0.1 s, the other 0.01)
    snap = {f: (run / f).stat().st_mtime_ns for f in ("model.pt", "train.json", "loss.csv", "loss.png")}
    assert main(["train", str(tiny_config), "--dataset", str(synthetic_dataset), "-o", str(run), "--steps", "2"]) == 0
    assert snap == {f: (run / f).stat().st_mtime_ns for f in snap}
    # a file of the run the user changed is never written over (a trial's own model.pt was replaced)
    mine = (run / "model.pt").read_bytes()
    (run / "model.pt").write_bytes(b"my fine-tuned weights")
    capsys.readouterr()
    assert main(["train", str(tiny_config), "--dataset", str(synthetic_dataset), "-o", str(run), "--steps", "3"]) == 1
    err = capsys.readouterr().err
    assert "model.pt: changed since segadeform train wrote it" in err and err.count("\n") == 1, err
    assert (run / "model.pt").read_bytes() == b"my fine-tuned weights"
    (run / "model.pt").write_bytes(mine)
    out = tmp_path / "eval"
    assert (
        main(["eval", str(synthetic_dataset), "-m", "lbs=lbs", "-m", f"sega={run / 'model.pt'}", "-o", str(out)]) == 0
    )
    said = capsys.readouterr()
    text = said.out
    assert "| lbs |" in text and "| sega |" in text
    assert "trained on" not in said.err  # the test split: held out
    # scored on its own training samples: said (a researcher's trial: eval took them without a word)
    args = ["eval", str(synthetic_dataset), "-m", f"sega={run / 'model.pt'}", "--split", "train"]
    assert main([*args, "-o", str(tmp_path / "on_train")]) == 0
    n_train = len(json.loads((run / "train.json").read_text())["samples"])
    err = capsys.readouterr().err
    assert f"warning: model sega was trained on {n_train} of the {n_train} 'train' samples" in err, err
    for f in (
        "eval.md",
        "eval.json",
        "error_per_frame.png",
        "error_per_band.png",
        "error_map.png",
        "error_vs_cost.png",
    ):
        assert (out / f).stat().st_size > 100
    # each sample's error, in eval.json and as a table in eval.md (a researcher's trial: six samples of their own,
    # read one by one); the overall vertex error is their plain mean
    res = json.loads((out / "eval.json").read_text())
    assert list(res["by_sample"]) == res["samples"]
    for n, m in res["models"].items():
        mean = np.mean([r["vertex_cm"][n] for r in res["by_sample"].values()])
        assert abs(mean - m["vertex_cm"]) < 1e-9, (n, mean, m["vertex_cm"])
    md = (out / "eval.md").read_text()
    assert "Per sample (vertex error, cm):" in md and all(f"| {sid} | " in md for sid in res["samples"])
    assert main(["eval", str(synthetic_dataset), "-m", "nonsense", "-o", str(out)]) == 2
    # a name given twice dropped the first model from the table without a word (a user's trial)
    assert main(["eval", str(synthetic_dataset), "-m", "a=lbs", "-m", "a=lbs-smooth", "-o", str(tmp_path / "d")]) == 2
    assert "'a' is given twice (lbs and lbs-smooth)" in capsys.readouterr().err
    # a second --split: the last one was evaluated alone (a user's trial); refused before anything is written
    args = ["eval", str(synthetic_dataset), "-m", "lbs=lbs", "--split", "test", "--split", "train"]
    assert main([*args, "-o", str(tmp_path / "two")]) == 2 and not (tmp_path / "two").exists()
    assert "Error: --split names one split (a report is of one), got 2: test, train;" in capsys.readouterr().err
    assert main(["train", str(tiny_config), "-o", str(tmp_path / "x")]) == 1  # no dataset named anywhere


def test_evaluate_packages_with_effects_off(synthetic_dataset, random_package, body):
    pkg = str(random_package)
    res = evaluate(
        synthetic_dataset,
        body,
        make_predictors(
            {"all": pkg, "no wrinkles": f"{pkg}:-wrinkles", "static": f"{pkg}:-dynamics"}, package=PackagePredictor
        ),
    )
    m = res["models"]
    assert all(np.isfinite(m[n][k]) for n in m for k in METRICS) and all(m[n]["ms_per_frame"] > 0 for n in m)
    assert m["all"]["vertex_cm"] != m["no wrinkles"]["vertex_cm"]
    from segadeform.errors import InputError

    with pytest.raises(InputError):
        evaluate(synthetic_dataset, body, make_predictors({"x": f"{pkg}:collisions"}, package=PackagePredictor))


def test_push_out_frames_is_the_runtime_collider_and_matches_the_reference(synthetic_dataset, body):
    """Evaluation pushes out with the runtime's BodyCollider, batched; the result agrees with the per-frame
    reference (BodyProxy + push_out); margins given as a list name one row each."""
    from segadeform.body.collision import BodyCollider, BodyProxy, push_out
    from segadeform.dataset.store import load_sample
    from segadeform.errors import InputError
    from segadeform.train.evaluate import push_out_frames, push_out_names
    from segadeform.train.metrics import reference

    s = load_sample(synthetic_dataset, "skirt__b0__swing")
    ref = reference(s, body)
    assert ref.posed.shape == (len(s.frames), len(body.v_template), 3)
    x = ref.gt - 0.01 * ref.n_gt  # 1 cm inwards: many vertices inside or within the margin
    fast = push_out_frames(x, ref, BodyCollider(body.v_template, body.faces), 0.004, batch=5)
    slow = np.stack([push_out(x[t], BodyProxy(ref.posed[t], body.faces), 0.004)[0] for t in range(len(x))])
    assert np.abs(fast - x).max() > 1e-3  # something moved
    np.testing.assert_allclose(fast, slow, atol=1e-6)
    assert push_out_names(0.004) == {" + push-out": 0.004}
    assert push_out_names([0.002, 0.008]) == {" + push-out 2 mm": 0.002, " + push-out 8 mm": 0.008}
    assert push_out_names(None) == {}
    with pytest.raises(InputError):
        push_out_names([-0.001])


def _with_val_split(synthetic_dataset, ds):
    """A copy of the synthetic dataset at ``ds`` whose test sample (the swing) serves as the validation split."""
    import shutil

    shutil.copytree(synthetic_dataset / "samples", ds / "samples")
    for p in (ds / "samples").glob("*__swing.json"):
        meta = json.loads(p.read_text())
        meta["split"] = "val"
        p.write_text(json.dumps(meta))
    return ds


def test_train_on_a_pack_with_a_validation_split_and_batches_of_garments(synthetic_dataset, tmp_path, body):
    """Training reads a read-only pack (caches go to the run folder, the pack is never written), takes
    several garments per step, and the validation split picks the checkpoint that becomes model.pt."""
    import hashlib

    from segadeform.dataset.pack import write_pack

    ds = _with_val_split(synthetic_dataset, tmp_path / "ds")
    pack = tmp_path / "store" / "a.sgdpack"
    pack.parent.mkdir()
    write_pack(ds, pack, body=body)
    digest = hashlib.sha256(pack.read_bytes()).hexdigest()
    cfg_p = tmp_path / "t.toml"
    cfg_p.write_text(
        f"[data]\ndataset = '{pack.parent}'\noptional = ['{tmp_path / 'absent'}']\nval_split = 'val'\n"
        "[model]\nhidden = 16\nlstm_hidden = 16\n"
        "[optim]\nsteps = 6\nframes = 3\ngarments = 2\ncheckpoint_every = 2\nlr = 0.003\n"
    )
    cfg = load_train_config(cfg_p)
    run = tmp_path / "run"
    final = train(cfg, run, body, log_every=2)
    assert hashlib.sha256(pack.read_bytes()).hexdigest() == digest and sorted(
        p.name for p in pack.parent.iterdir()
    ) == ["a.sgdpack"]
    assert any((run / "cache").glob("asset-*.npz")) and any((run / "cache").glob("contact-*.npz"))
    info = json.loads((run / "train.json").read_text())
    rows = list(csv.DictReader(open(run / "loss.csv")))
    vals = {int(r["step"]): float(r["val_vertex"]) for r in rows if r["val_vertex"]}
    assert sorted(vals) == [2, 4, 6] and info["sample_frames_seen"] == 6 * 2 * 3
    best = min(vals, key=vals.get)
    step0 = torch.load(run / "best.pt", weights_only=False)
    # the untrained model (step 0: the prior's LBS) was a candidate too
    assert info["chosen"]["step"] in (0, best) and info["chosen"]["val_split"] == "val"
    assert info["chosen"]["val_vertex"] <= vals[best] + 1e-12 and step0["step"] == info["chosen"]["step"]
    chosen = torch.load(run / "best.pt", weights_only=False)
    final_sd = torch.load(final, weights_only=True)["state_dict"]
    assert all(torch.equal(chosen["state_dict"][k], final_sd[k]) for k in final_sd)
    assert sorted(info["samples"]) == ["shorts__b0__walk", "skirt__b0__walk"]  # validation never trained on


def test_several_splits_train_together_and_validation_must_be_apart(synthetic_dataset, tmp_path, body):
    """``split = "train+val"``: a final fit on the training and validation samples at a step count chosen on
    validation before; every sample of both is trained on, the test split's never; val_split may not be one of them,
    a split named twice or an empty part is refused, and so is a part the dataset has no sample of (a typo)."""
    from segadeform.errors import FileFormatError, InputError

    ds = _with_val_split(synthetic_dataset, tmp_path / "ds")
    base = "[model]\nhidden = 16\nlstm_hidden = 16\n[optim]\nsteps = 2\nframes = 2\n"
    cfg_p = tmp_path / "t.toml"
    cfg_p.write_text(f"[data]\ndataset = '{ds}'\nsplit = 'train+val'\n" + base)
    train(load_train_config(cfg_p), tmp_path / "both", body)
    both = json.loads((tmp_path / "both" / "train.json").read_text())["samples"]
    cfg_p.write_text(f"[data]\ndataset = '{ds}'\n" + base)
    train(load_train_config(cfg_p), tmp_path / "one", body)
    one = json.loads((tmp_path / "one" / "train.json").read_text())["samples"]
    val = [p.stem for p in (ds / "samples").glob("*__swing.json")]
    assert val and sorted(both) == sorted(one + val) and not set(one) & set(val)
    cfg_p.write_text(f"[data]\ndataset = '{ds}'\nsplit = 'train+vall'\n" + base)
    with pytest.raises(
        InputError, match=r"no 'vall' samples in the dataset \(data.split = 'train\+vall'\).*train \| val"
    ):
        train(load_train_config(cfg_p), tmp_path / "typo", body)
    assert not (tmp_path / "typo").exists()
    for split, extra, words in (
        ("train+val", "val_split = 'val'\n", "val_split must name a split other than the training ones"),
        ("train+train", "", "must name a split, or several joined by"),
        ("train+", "", "must name a split, or several joined by"),
    ):
        cfg_p.write_text(f"[data]\ndataset = '{ds}'\nsplit = '{split}'\n{extra}" + base)
        with pytest.raises(FileFormatError, match=words):
            load_train_config(cfg_p)


def test_warmup_then_cosine_and_a_time_budget_that_fixes_the_step_count(synthetic_dataset, tmp_path, body, monkeypatch):
    """optim.warmup ramps the rate linearly, then the cosine decays it; optim.seconds times the warm-up and
    fixes the step count (recorded), and --steps with that count reruns the same schedule."""
    from segadeform.errors import FileFormatError
    from segadeform.train.config import OptimConfig

    o = OptimConfig(steps=100, lr=1.0, warmup=10, lr_final=0.1)
    assert o.lr_factor(0, 100) == pytest.approx(0.1) and o.lr_factor(9, 100) == pytest.approx(1.0)
    assert o.lr_factor(10, 100) == pytest.approx(1.0) and o.lr_factor(100, 100) == pytest.approx(0.1)
    assert o.lr_factor(55, 100) == pytest.approx(0.55)  # half-way through the decay
    assert o.lr_factor(5, 30) == o.lr_factor(5, 1000)  # the warm-up never depends on the count
    plain = OptimConfig(steps=50)
    # no warm-up: the cosine as it always was, to the bit (older runs resume and rerun exactly)
    old = lambda s, n: 0.1 + (1 - 0.1) * 0.5 * (1 + np.cos(np.pi * min(s, n) / n))  # noqa: E731
    assert all(plain.lr_factor(s, n) == old(s, n) for n in (7, 50, 2500, 3000) for s in range(n + 3))
    assert all(plain.prior_fade(s, n, 0.5) == max(0.0, 1.0 - s / (0.5 * n)) for n in (50, 2500) for s in range(n))
    assert OptimConfig(steps=100, warmup=20).prior_fade(5, 100, 0.0) == 0.0  # no prior: none in the warm-up
    # the count that fits: 20 steps took 10 s, one more takes 0.5 s, 30 s in all -> 20 + 0.9 x 40
    b = OptimConfig(steps=1000, seconds=30.0, warmup=20)
    assert b.budget_steps(20, 10.0, 0.5) == 56
    assert b.budget_steps(20, 40.0, 0.5) == 20  # already over: stop at the end of the warm-up
    assert OptimConfig(steps=50, seconds=30.0, warmup=20).budget_steps(20, 10.0, 0.5) == 50  # capped at steps

    # the trainer's clock is a virtual one: a training step takes STEP seconds of it and a validation VAL, nothing
    # else any (a wall-clock budget of 5 s failed on a loaded machine); the budget's rule is what is tested
    import segadeform.train.trainer as trainer_mod

    STEP = VAL = 0.125  # (binary fractions: the sums are exact)
    clock = {"now": 1000.0, "steps": 0, "slow": 0.0}
    fast = trainer_mod.step_losses

    def timed(*a, **k):
        if "prior_scale" in k:  # a training step (validation calls it without)
            clock["steps"] += 1
            assert clock["steps"] <= 200, "the budget never stopped the run"
            clock["now"] += STEP + (clock["slow"] if clock["steps"] > 20 else 0.0)
        else:
            clock["now"] += VAL
        return fast(*a, **k)

    monkeypatch.setattr(trainer_mod, "step_losses", timed)
    monkeypatch.setattr(trainer_mod, "time", SimpleNamespace(perf_counter=lambda: clock["now"]))

    def run(cfg, out):
        clock["steps"] = 0
        t0 = clock["now"]
        train(cfg, out, body, log_every=10)
        return json.loads((out / "train.json").read_text()), clock["now"] - t0

    cfg_path = tmp_path / "budget.toml"
    cfg_path.write_text(
        "[model]\nhidden = 16\nlstm_hidden = 16\n"
        "[optim]\nsteps = 100000\nframes = 3\ncheckpoint_every = 10\nlr = 0.003\nwarmup = 20\nseconds = 4\n"
    )
    cfg = load_train_config(cfg_path, dataset=synthetic_dataset)
    info, took = run(cfg, tmp_path / "b")
    n = info["time_budget"]["steps_chosen"]
    # the 20 warm-up steps took 2.5 s, 0.125 s a step: the count that fits the other 1.5 s, less 10 % -- and no more
    assert n == cfg.optim.budget_steps(20, 20 * STEP, STEP) == 30 and info["stopped_at_budget"] is None
    assert info["steps"] == n and info["time_budget"]["seconds"] == 4 and took == n * STEP <= 4
    rows = list(csv.DictReader(open(tmp_path / "b" / "loss.csv")))
    assert int(rows[-1]["step"]) == n
    # the same count without the budget: the same schedule, the same learning rates logged, the same weights
    again = load_train_config(cfg_path, dataset=synthetic_dataset, overrides={"optim.seconds": 0, "optim.steps": n})
    run(again, tmp_path / "c")
    rows_c = list(csv.DictReader(open(tmp_path / "c" / "loss.csv")))
    assert [r["lr"] for r in rows] == [r["lr"] for r in rows_c]
    wb = torch.load(tmp_path / "b" / "last.pt", weights_only=False)["state_dict"]
    wc = torch.load(tmp_path / "c" / "last.pt", weights_only=False)["state_dict"]
    assert all(torch.equal(wb[k], wc[k]) for k in wb)  # the budget only chose the count
    # steps that slow down after the warm-up (other runs sharing the machine) do not overrun the budget: the run
    # stops, the validation's choice so far is its model (five GPU runs of 28 Nov overran and lost it)
    slow = tmp_path / "slow.toml"
    slow.write_text(
        '[data]\nval_split = "test"\n[model]\nhidden = 16\nlstm_hidden = 16\n'
        "[optim]\nsteps = 100000\nframes = 3\ncheckpoint_every = 10\nlr = 0.003\nwarmup = 20\nseconds = 5\n"
    )
    clock["slow"] = 0.5  # each step past the warm-up's 20 takes 0.5 s more than the warm-up said
    info, took = run(load_train_config(slow, dataset=synthetic_dataset), tmp_path / "s")
    # validations at steps 0, 10 and 20, the warm-up's 20 steps: 2.875 s; then 0.625 s a step: the 24th would end
    # at 5.375 s, past the budget of 5 s, which a count of 33 (chosen at the warm-up's pace) would have run to
    assert info["time_budget"]["steps_chosen"] == 33 and info["stopped_at_budget"] == info["steps"] == 23
    assert (tmp_path / "s" / "model.pt").is_file() and info["chosen"]["step"] <= info["steps"]
    assert took == 3 * VAL + 20 * STEP + 3 * (STEP + 0.5) <= 5  # the budget held
    # a budget needs a warm-up to time the machine
    bad = tmp_path / "bad.toml"
    bad.write_text("[optim]\nsteps = 50\nseconds = 10\nwarmup = 5\n")
    with pytest.raises(FileFormatError, match="warmup >= 20"):
        load_train_config(bad, dataset=synthetic_dataset)
    bad.write_text("[optim]\nsteps = 50\nseconds = inf\nwarmup = 20\n")
    with pytest.raises(FileFormatError, match="finite"):
        load_train_config(bad, dataset=synthetic_dataset)


def test_weight_decay_is_decoupled_and_off_by_default(synthetic_dataset, tmp_path, body):
    """optim.weight_decay > 0 trains with AdamW at that decay (the residual shrinks towards the prior); 0 keeps
    plain Adam, the optimiser of every earlier run; a bad value is refused with what was expected."""
    from segadeform.errors import FileFormatError

    cfgs = {}
    for name, wd in (("plain", None), ("decay", 0.5)):
        p = tmp_path / f"{name}.toml"
        extra = f"weight_decay = {wd}\n" if wd is not None else ""
        p.write_text("[model]\nhidden = 16\nlstm_hidden = 16\n[optim]\nsteps = 3\nframes = 2\n" + extra)
        cfgs[name] = load_train_config(p, dataset=synthetic_dataset)
        train(cfgs[name], tmp_path / name, body, log_every=10)
    assert cfgs["plain"].optim.weight_decay == 0.0 and cfgs["decay"].optim.weight_decay == 0.5
    opt = {n: torch.load(tmp_path / n / "last.pt", weights_only=False)["optimizer"] for n in cfgs}
    assert opt["plain"]["param_groups"][0]["weight_decay"] == 0.0
    assert opt["decay"]["param_groups"][0]["weight_decay"] == 0.5
    assert (
        "decoupled_weight_decay" not in opt["plain"]["param_groups"][0]
        or not opt["plain"]["param_groups"][0]["decoupled_weight_decay"]
    )
    sd = {n: torch.load(tmp_path / n / "last.pt", weights_only=False)["state_dict"] for n in cfgs}
    assert any(not torch.equal(sd["plain"][k], sd["decay"][k]) for k in sd["plain"])
    bad = tmp_path / "bad.toml"
    for v in ("-0.1", "1.5", "nan", "true"):
        bad.write_text(f"[optim]\nsteps = 5\nweight_decay = {v}\n")
        with pytest.raises(FileFormatError, match="weight_decay"):
            load_train_config(bad, dataset=synthetic_dataset)


def test_collision_near_trains_and_a_bad_value_is_refused(synthetic_dataset, tmp_path, body):
    """loss.collision_near reaches the loss (a run with it differs from one without) and must be >= 0 metres."""
    from segadeform.errors import FileFormatError

    sd = {}
    for name, near in (("all", None), ("near", 0.001)):
        p = tmp_path / f"{name}.toml"
        extra = f"collision_near = {near}\n" if near is not None else ""
        p.write_text(
            "[model]\nhidden = 16\nlstm_hidden = 16\n[loss]\ncollision = 1000.0\ncollision_power = 1\n"
            "collision_margin = 0.05\n" + extra + "[optim]\nsteps = 3\nframes = 2\n"
        )
        cfg = load_train_config(p, dataset=synthetic_dataset)
        assert cfg.loss.collision_near == (near or 0.0)
        train(cfg, tmp_path / name, body, log_every=10)
        sd[name] = torch.load(tmp_path / name / "last.pt", weights_only=False)["state_dict"]
    assert any(not torch.equal(sd["all"][k], sd["near"][k]) for k in sd["all"])
    bad = tmp_path / "bad.toml"
    for v in ("-0.01", "nan"):
        bad.write_text(f"[loss]\ncollision_near = {v}\n")
        with pytest.raises(FileFormatError, match="collision_near"):
            load_train_config(bad, dataset=synthetic_dataset)


def test_collision_types_weigh_each_garment_type_and_bad_entries_are_refused(synthetic_dataset, tmp_path, body):
    """loss.collision_types: naming every type's weight trains exactly as the same global weight does, a type
    set apart trains differently, and an unknown type or a bad weight is refused naming the key."""
    from segadeform.errors import FileFormatError

    head = "[model]\nhidden = 16\nlstm_hidden = 16\n[loss]\ncollision_power = 1\ncollision_margin = 0.05\n"
    runs = {
        "global": "collision = 1000.0\n",
        "by_type": "collision = 0.0\ncollision_types = { skirt = 1000.0, trousers = 1000.0 }\n",
        "apart": "collision = 1000.0\ncollision_types = { trousers = 0.0 }\n",
    }
    sd = {}
    for name, loss in runs.items():
        p = tmp_path / f"{name}.toml"
        p.write_text(head + loss + "[optim]\nsteps = 3\nframes = 2\n")
        cfg = load_train_config(p, dataset=synthetic_dataset)
        train(cfg, tmp_path / name, body, log_every=10)
        sd[name] = torch.load(tmp_path / name / "last.pt", weights_only=False)["state_dict"]
    assert cfg.loss.collision_for("trousers") == 0.0 and cfg.loss.collision_for("skirt") == 1000.0
    assert all(torch.equal(sd["global"][k], sd["by_type"][k]) for k in sd["global"])
    assert any(not torch.equal(sd["global"][k], sd["apart"][k]) for k in sd["global"])
    bad = tmp_path / "bad.toml"
    for entry, match in (
        ("shirt = 1.0", "unknown garment type"),
        ("top = -1.0", "collision_types.top"),
        ("top = nan", "collision_types.top"),
    ):
        bad.write_text(f"[loss]\ncollision_types = {{ {entry} }}\n")
        with pytest.raises(FileFormatError, match=match):
            load_train_config(bad, dataset=synthetic_dataset)


def test_a_history_model_runs_from_the_lead_trains_and_evaluates(synthetic_dataset, tmp_path, body):
    """ModelConfig.history: a sample's history inputs are its lead's frames then its own (history_in[lead + t]
    is frame t), the training step reads the state at lead + t, and a trained history model evaluates."""
    import torch

    from segadeform.dataset.roots import DatasetRoots
    from segadeform.model import ModelConfig, SEGANet
    from segadeform.motion import history_inputs
    from segadeform.train.data import load_items
    from segadeform.train.trainer import _history

    roots = DatasetRoots([synthetic_dataset])
    it, other = load_items(roots, body, n_star=32, window=5, n_betas=10, ids=["skirt__b0__walk", "shorts__b0__walk"])
    s = roots.load("skirt__b0__walk")
    assert it.lead == 4 and other.lead == 0 and it.history_in.shape == (4 + it.n_frames, 75)
    ref = history_inputs(np.concatenate([s.lead_poses, s.poses]), np.concatenate([s.lead_trans, s.trans]), 30.0)
    np.testing.assert_allclose(it.history_in.numpy(), ref, atol=1e-6)
    net = SEGANet(ModelConfig(hidden=16, lstm_hidden=16, history=4))
    rows = torch.tensor([4, 6, 9])
    with torch.no_grad():
        full = net.history_states(it.history_in[None])[0]
        torch.testing.assert_close(_history(net, it.history_in, rows), full[rows])
        assert _history(SEGANet(ModelConfig(hidden=16, lstm_hidden=16)), it.history_in, rows) is None
    # the training step and the checkpoint predictor read the state at lead + t (gates open: the state matters)
    from segadeform.body.transfer import RESIDUAL_EPS
    from segadeform.model.network import save_checkpoint
    from segadeform.train.config import LossWeights
    from segadeform.train.data import sample_asset
    from segadeform.train.predictors import CheckpointPredictor
    from segadeform.train.trainer import step_losses

    net.eval()  # (training mode steps the spectral norms' power iteration at every call)
    with torch.no_grad():
        net.weight_gate.fill_(1.0)
        net.blend_gate.fill_(1.0)
    t = torch.arange(it.n_frames)

    def by_hand(rows):
        with torch.no_grad():
            v, _, _ = net(
                it.features,
                it.nbr,
                it.mask,
                it.descriptor,
                it.betas.expand(len(t), -1),
                it.windows[t],
                it.skin_rest,
                it.joints[None].expand(len(t), -1, -1),
                it.trans[t],
                torch.log(it.body_weights + RESIDUAL_EPS),
                full[rows],
            )
        return v

    with torch.no_grad():
        full = net.history_states(it.history_in[None])[0]
        got = float(step_losses(net, it, t, LossWeights())["vertex"])
    right, wrong = by_hand(4 + t), by_hand(t)
    assert (right - wrong).abs().max() > 1e-3  # the offset shows in the frames (far above the tolerances below)
    assert abs(got - float((right - it.frames).norm(dim=-1).mean())) < 1e-6
    pred = CheckpointPredictor(save_checkpoint(tmp_path / "h.pt", net)).predict(
        s, body, sample_asset(roots, s, body, 32)
    )
    np.testing.assert_allclose(pred, right.numpy(), atol=1e-5)
    cfg_p = tmp_path / "h.toml"
    cfg_p.write_text(
        "[model]\nhidden = 16\nlstm_hidden = 16\nhistory = 4\n"
        "[optim]\nsteps = 4\nframes = 3\ncheckpoint_every = 2\nlr = 0.003\n"
    )
    ck = train(load_train_config(cfg_p, dataset=synthetic_dataset), tmp_path / "run", body)
    info = json.loads((tmp_path / "run" / "train.json").read_text())
    assert info["history_without_lead"] == ["shorts__b0__walk"]  # the sample that records none
    res = evaluate(synthetic_dataset, body, make_predictors({"lbs": "lbs", "hist": str(ck)}))
    assert np.isfinite(res["models"]["hist"]["vertex_cm"])


def test_late_terms_count_only_the_vertex_error_and_the_prior_before_their_start(
    synthetic_dataset, tmp_path, body, monkeypatch
):
    """``loss.terms_from``: before that fraction of the steps the total is the vertex error (and the fading
    skin-weight prior) alone, from it on every term at its weight; 0 (the default) is the total as before."""
    import torch

    from segadeform.dataset.roots import DatasetRoots
    from segadeform.errors import FileFormatError
    from segadeform.model import ModelConfig, SEGANet
    from segadeform.train import trainer as trainer_mod
    from segadeform.train.config import LossWeights
    from segadeform.train.data import load_items
    from segadeform.train.trainer import TERMS, step_losses

    (it,) = load_items(
        DatasetRoots([synthetic_dataset]), body, n_star=32, window=5, n_betas=10, ids=["skirt__b0__walk"]
    )
    net = SEGANet(ModelConfig(hidden=16, lstm_hidden=16)).eval()
    w = LossWeights(collision_margin=0.05)
    t = torch.arange(3)
    with torch.no_grad():
        full = step_losses(net, it, t, w, prior_scale=0.5)
        early = step_losses(net, it, t, w, prior_scale=0.5, terms_scale=0.0)
    others = sum(getattr(w, k) * full[k] for k in TERMS if k not in ("vertex", "skin_prior") and getattr(w, k))
    assert float(others) > 1e-4  # the other terms are not zero here, so the test can tell
    assert (
        abs(float(early["total"]) - float(w.vertex * full["vertex"] + 0.5 * w.skin_prior * full["skin_prior"])) < 1e-6
    )
    assert abs(float(full["total"]) - float(early["total"] + others)) < 1e-5
    # the trainer: the step's scale is 0 before terms_from * steps and 1 from there on
    seen = []

    def spy(*a, **kw):
        seen.append(kw.get("terms_scale", 1.0))
        return step_losses(*a, **kw)

    p = tmp_path / "late.toml"
    for frac, want in (("0.5", [0.0, 0.0, 1.0, 1.0]), ("0.0", [1.0] * 4)):
        seen.clear()
        p.write_text(
            f"[model]\nhidden = 16\nlstm_hidden = 16\n[loss]\nterms_from = {frac}\n[optim]\nsteps = 4\nframes = 2\n"
        )
        with monkeypatch.context() as mp:
            mp.setattr(trainer_mod, "step_losses", spy)
            train(load_train_config(p, dataset=synthetic_dataset), tmp_path / f"run{frac}", body, log_every=10)
        assert seen == want
    for bad in ("1.0", "-0.1"):
        p.write_text(f"[loss]\nterms_from = {bad}\n")
        with pytest.raises(FileFormatError, match="terms_from"):
            load_train_config(p, dataset=synthetic_dataset)


def test_with_late_terms_validation_chooses_among_checkpoints_trained_on_the_whole_loss(
    synthetic_dataset, tmp_path, body
):
    """``loss.terms_from``: a checkpoint of the vertex error alone is never the chosen model (only the untrained
    model and those after terms_from are candidates), even where one of them has the lowest validation error."""
    ds = _with_val_split(synthetic_dataset, tmp_path / "ds")
    cfg_p = tmp_path / "t.toml"
    cfg_p.write_text(
        f"[data]\ndataset = '{ds}'\nval_split = 'val'\n[model]\nhidden = 16\nlstm_hidden = 16\nweights = 'free'\n"
        "[loss]\nterms_from = 0.5\ncollision = 300.0\ncollision_margin = 0.2\nedge = 30.0\n"
        "[optim]\nsteps = 8\nframes = 3\ncheckpoint_every = 1\nlr = 0.01\n"
    )
    run = tmp_path / "run"
    train(load_train_config(cfg_p), run, body, log_every=1)
    info = json.loads((run / "train.json").read_text())
    vals = {int(r["step"]): float(r["val_vertex"]) for r in csv.DictReader(open(run / "loss.csv")) if r["val_vertex"]}
    assert sorted(vals) == list(range(1, 9))
    early = min(vals[s] for s in range(1, 5))  # checkpoints 1-4 saw the vertex error alone
    eligible = [vals[s] for s in range(5, 9)]
    assert early < min(eligible)  # so the rule decides here: without it step 1-4 would be chosen
    assert info["chosen"]["step"] >= 5  # (free weights: the untrained model is far off, never chosen here)
    assert info["chosen"]["val_vertex"] <= min(eligible) + 1e-12


def test_a_run_folders_copy_of_its_config_trains_as_the_original(synthetic_dataset, tmp_path, body):
    """A user's trial: `train RUN/config.toml -o NEW` looked for the config's relative dataset beside the run folder
    ("dataset root does not exist").  The copy now names the folder its relative paths are from on its first line:
    it reads the same dataset, has the same digest (so it also resumes the run), and trains."""
    import shutil

    from segadeform.train.config import COPY_MARK

    cfg_dir = tmp_path / "project"
    shutil.copytree(synthetic_dataset, cfg_dir / "ds")
    (cfg_dir / "my.toml").write_text(
        '[data]\ndataset = "ds"\n[model]\nhidden = 16\nlstm_hidden = 16\n[optim]\nsteps = 2\nframes = 3\nlr = 0.003\n'
    )
    cfg = load_train_config(cfg_dir / "my.toml")
    train(cfg, tmp_path / "runs" / "a", body)
    copy = tmp_path / "runs" / "a" / "config.toml"
    assert copy.read_text().startswith(COPY_MARK) and copy.read_text().endswith((cfg_dir / "my.toml").read_text())
    again = load_train_config(copy)
    assert again.dataset == cfg.dataset and again.digest() == cfg.digest()
    train(again, tmp_path / "runs" / "a", body)  # the copy resumes the run (done: nothing to do)
    train(again, tmp_path / "runs" / "b", body)  # and trains a new one
    assert (tmp_path / "runs" / "b" / "model.pt").is_file()
    assert (tmp_path / "runs" / "b" / "config.toml").read_text() == copy.read_text()  # a copy of a copy: one mark


def test_mirror_trains_on_each_samples_mirror_image_and_needs_a_symmetric_body(
    synthetic_dataset, tmp_path, body, monkeypatch
):
    """data.mirror: each training sample is followed by its left-right mirror image, which skinning poses as it
    does the original (the same LBS error); validation samples are not mirrored; an asymmetric body is refused."""
    import dataclasses

    from segadeform.body.transfer import skin_garment
    from segadeform.dataset.mirror import body_asymmetry
    from segadeform.dataset.roots import DatasetRoots
    from segadeform.errors import InputError
    from segadeform.motion.mirror import mirror_joint_order, mirror_points, mirror_poses
    from segadeform.train import trainer as T
    from segadeform.train.data import load_items

    roots = DatasetRoots([synthetic_dataset])
    kw = dict(n_star=32, window=5, n_betas=10, weight_prior="nearest")
    it, mi = load_items(roots, body, **kw, ids=["skirt__b0__walk"], mirror=True)
    assert (it.id, mi.id) == ("skirt__b0__walk", "skirt__b0__walk~mirror") and mi.meta["mirror_of"] == it.id
    np.testing.assert_allclose(mi.frames.numpy(), mirror_points(it.frames.numpy()))
    assert mi.lead == it.lead == 4
    # the network's inputs are the mirrored motion's: its windows, and its history from the mirrored lead on
    from segadeform.dataset.mirror import mirror_sample
    from segadeform.motion import history_inputs, motion_windows

    s = roots.load("skirt__b0__walk")
    mp = mirror_poses(s.poses, body.joint_names)
    np.testing.assert_allclose(mi.windows.numpy(), motion_windows(mp, 5), atol=1e-6)
    ref = history_inputs(
        np.concatenate([mirror_poses(s.lead_poses, body.joint_names), mp]),
        np.concatenate([mirror_points(s.lead_trans), mirror_points(s.trans)]),
        30.0,
    )
    np.testing.assert_allclose(mi.history_in.numpy(), ref, atol=1e-6)
    assert np.abs(mi.windows.numpy() - it.windows.numpy()).max() > 0.1  # not the original's
    # stored contacts (the synthetic samples store none) are mirrored points and normals
    rng = np.random.default_rng(0)
    cp, cn = rng.normal(size=s.frames.shape), rng.normal(size=s.frames.shape)
    m = mirror_sample(dataclasses.replace(s, contact_p=cp, contact_n=cn), body.joint_names)
    np.testing.assert_array_equal(m.contact_p, cp * [-1, 1, 1])
    np.testing.assert_array_equal(m.contact_n, cn * [-1, 1, 1])
    # the prior's weights are the original's with left and right swapped (the body is symmetric) ...
    perm = mirror_joint_order(body.joint_names)
    assert np.abs(mi.body_weights.numpy()[:, perm] - it.body_weights.numpy()).mean() < 0.01
    # ... and skinning the mirror image with them is as far from its frames as the original is from its own

    poses = roots.load("skirt__b0__walk").poses

    def lbs_error(x, p):
        s = skin_garment(x.rest.numpy(), x.body_weights.numpy(), body, p, None, x.trans.numpy())
        return float(np.linalg.norm(s - x.frames.numpy(), axis=-1).mean())

    e, em = lbs_error(it, poses), lbs_error(mi, mirror_poses(poses, body.joint_names))
    assert 0.002 < e and abs(em - e) < 0.05 * e, (e, em)
    # a run with it trains on both and validates on the originals
    p = tmp_path / "mirror.toml"
    p.write_text(
        "[data]\nmirror = true\nval_split = 'test'\n[model]\nhidden = 16\nlstm_hidden = 16\n[optim]\nsteps = 2\n"
    )
    cfg = load_train_config(p, dataset=synthetic_dataset)
    assert cfg.mirror and cfg.to_dict()["mirror"] is True
    seen = []
    real = T.load_items
    monkeypatch.setattr(T, "load_items", lambda *a, **k: seen.append(k.get("mirror", False)) or real(*a, **k))
    train(cfg, tmp_path / "run", body, log_every=10)
    assert seen == [True, False]  # the training samples mirrored, the validation ones not
    # a body whose left side is not its right side's mirror image is refused before the run starts
    jt = body.rest_joints()[0]
    lopsided = dataclasses.replace(
        body,
        J_regressor=None,
        joint_template=jt + np.where(jt[:, :1] > 0, 0.03, 0),
        joint_shapedirs=np.zeros(jt.shape + (body.n_betas,)),
    )
    assert body_asymmetry(lopsided) > 0.02 and body_asymmetry(body) < T.MIRROR_TOLERANCE
    monkeypatch.setattr(T, "body_asymmetry", lambda b, betas=None: body_asymmetry(lopsided, betas))
    with pytest.raises(InputError, match="symmetric body"):
        train(cfg, tmp_path / "run2", body, log_every=10)
    assert not (tmp_path / "run2").exists()


def test_a_run_starts_from_a_checkpoint_to_fine_tune_and_refuses_another_models(
    synthetic_dataset, tiny_config, tmp_path, body, capsys, caplog
):
    """optim.init / `train --init`: a new run starts from a trained model's weights (a user's trial: fine-tuning the
    shipped model on one's own samples had no way); a checkpoint of another [model] is refused before anything is
    written, naming the fields."""
    from segadeform.cli.main import main

    first = tmp_path / "first"
    assert main(["train", str(tiny_config), "-o", str(first), "--dataset", str(synthetic_dataset)]) == 0
    start = torch.load(first / "model.pt", weights_only=True)["state_dict"]
    slow = tmp_path / "slow.toml"  # a step this small leaves the weights where they started
    slow.write_text(  # fine-tuned on the skirt alone
        '[data]\nexclude = ["shorts*"]\n'
        + tiny_config.read_text().replace("lr = 0.003", "lr = 1e-12").replace("steps = 6", "steps = 1")
    )
    tuned = tmp_path / "tuned"
    args = [
        "train",
        str(slow),
        "-o",
        str(tuned),
        "--dataset",
        str(synthetic_dataset),
        "--init",
        str(first / "model.pt"),
    ]
    assert main(args) == 0
    got = torch.load(tuned / "last.pt", weights_only=False)["state_dict"]
    weights = [k for k in start if not k.endswith("._u")]  # (the Lipschitz bounds' power iterations step on)
    assert len(weights) > 20 and all(torch.allclose(got[k], start[k], atol=1e-6) for k in weights)
    import hashlib

    info = json.loads((tuned / "train.json").read_text())
    assert info["samples"] == ["skirt__b0__walk"] and info["config"]["optim"]["init"] == str(first / "model.pt")
    assert info["init"]["sha256"] == hashlib.sha256((first / "model.pt").read_bytes()).hexdigest()
    # the tuned model saw the first one's garments too (the runtime's familiarity check reads them: a review)
    from segadeform.model.network import checkpoint_training_garments

    assert sorted(checkpoint_training_garments(tuned / "model.pt")[0]) == ["shorts", "skirt"]
    # and its training motions (a fine-tuned shipped model listed its own alone: an ML user's trial); a starting
    # checkpoint that records none is named, with the fix
    from segadeform.model.network import checkpoint_training_motions
    from segadeform.motion.fingerprint import read_motions_record

    names = sorted(n for n, _ in read_motions_record(checkpoint_training_motions(tuned / "model.pt")))
    assert names == ["shorts__b0__walk", "skirt__b0__walk"], names  # (the tuned run saw the skirt alone)
    ck = torch.load(first / "model.pt", weights_only=False)
    del ck["training_motions"]
    torch.save(ck, tmp_path / "nomo.pt")
    with caplog.at_level("WARNING", logger="segadeform.train.trainer"):
        assert main([*args[:3], str(tmp_path / "nomo"), *args[4:-1], str(tmp_path / "nomo.pt")]) == 0
    assert "nomo.pt records no training motions" in caplog.text and "--training-motions" in caplog.text
    fresh = tmp_path / "fresh"  # without it the run starts elsewhere
    assert main(["train", str(slow), "-o", str(fresh), "--dataset", str(synthetic_dataset)]) == 0
    other = torch.load(fresh / "last.pt", weights_only=False)["state_dict"]
    assert any(not torch.allclose(other[k], start[k], atol=1e-3) for k in weights)
    # a checkpoint of another [model]: one line naming the field, nothing written
    wide = tmp_path / "wide.toml"
    wide.write_text(tiny_config.read_text().replace("hidden = 16", "hidden = 8"))
    capsys.readouterr()
    args = ["train", str(wide), "-o", str(tmp_path / "w"), "--dataset", str(synthetic_dataset)]
    assert main([*args, "--init", str(first / "model.pt")]) == 1
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "another [model] config" in err and "model.hidden 16 -> 8" in err, err
    assert not (tmp_path / "w").exists()


def test_the_frames_seen_are_those_the_clips_have(synthetic_dataset, tiny_config, tmp_path, body):
    """`optim.frames` longer than the clips: each step sees every frame of a clip, and train.json counts those (it
    counted optim.frames: 300 where 45 were seen, a researcher's trial)."""
    import json

    from segadeform.dataset import list_samples, load_sample

    lengths = {
        len(load_sample(synthetic_dataset, s).frames)
        for s in list_samples(synthetic_dataset)
        if load_sample(synthetic_dataset, s).meta.get("split") == "train"
    }
    assert len(lengths) == 1 and (n := lengths.pop()) < 1000
    cfg = load_train_config(
        tiny_config,
        dataset=synthetic_dataset,
        overrides={"optim.steps": 2, "optim.frames": 1000, "optim.garments": 2, "data.val_split": ""},
    )
    train(cfg, tmp_path / "run", body)
    assert json.loads((tmp_path / "run" / "train.json").read_text())["sample_frames_seen"] == 2 * 2 * n


def test_eval_says_when_a_sample_plays_a_motion_the_model_was_trained_on(
    synthetic_dataset, tiny_config, tmp_path, body, capsys, monkeypatch, random_package
):
    """A researcher scored the shipped package on CMU clips it had been trained on, and nothing said so: a checkpoint
    records its training motions' fingerprints (segadeform.motion.fingerprint), export carries them into the
    manifest, and eval warns of samples that play one of them, for a checkpoint and for a package; the test split's
    arm swing is not taken for the walk."""
    import shutil

    from segadeform.model.network import checkpoint_training_motions
    from segadeform.motion.fingerprint import BASELINE, read_motions_record

    run = tmp_path / "r"
    final = train(load_train_config(tiny_config, dataset=synthetic_dataset, overrides={"optim.steps": 2}), run, body)
    record = checkpoint_training_motions(final)
    names = [n for n, _ in read_motions_record(record)]
    assert names == ["shorts__b0__walk", "skirt__b0__walk"]  # (the synthetic samples name no motion: their ids)
    lead = [sp for n, sp in read_motions_record(record) if n == "skirt__b0__walk"][0]
    assert len(lead) == 12 + 4 - BASELINE  # the lead's 4 frames and the 12 of the clip, a speed over each 3
    for split, said in (("train", True), ("test", False)):
        out = tmp_path / f"ev-{split}"
        assert main(["eval", str(synthetic_dataset), "-m", f"sega={final}", "--split", split, "-o", str(out)]) == 0
        err = capsys.readouterr().err
        assert ("warning: model sega was trained on the motion of 2 of the 2 'train' samples" in err) == said, err
        assert ("trained on the motion" in err) == said, err
    # export carries the record into the manifest (the export itself is stubbed: it takes minutes)
    manifests = []

    class Exported(Exception):
        pass

    def export_package(model, out, **kw):
        manifests.append(kw["extra_manifest"])
        raise Exported

    monkeypatch.setattr("segadeform.export.export_package", export_package)
    with pytest.raises(Exported):
        main(["export", str(final), "-o", str(tmp_path / "pkg")])
    assert manifests[-1]["training_motions"] == record
    # a package that records them: the same warning
    pkg = tmp_path / "pkg-with-motions"
    shutil.copytree(random_package, pkg)
    m = json.loads((pkg / "manifest.json").read_text())
    m["training_motions"] = record
    (pkg / "manifest.json").write_text(json.dumps(m))
    out = tmp_path / "ev-pkg"
    assert main(["eval", str(synthetic_dataset), "-m", f"p={pkg}", "--split", "train", "-o", str(out)]) == 0
    assert "warning: model p was trained on the motion of 2 of the 2 'train' samples" in capsys.readouterr().err
    # a record from another release cannot be compared: said, and the eval goes on
    m["training_motions"] = dict(record, rate=24.0)
    (pkg / "manifest.json").write_text(json.dumps(m))
    assert main(["eval", str(synthetic_dataset), "-m", f"p={pkg}", "--split", "train", "-o", str(out)]) == 0
    err = capsys.readouterr().err
    assert "model p's record of its training motions cannot be read: a training_motions record taken another way" in err


def test_a_dataset_config_s_training_motions_are_recorded_for_a_package():
    """``export --training-motions CONFIG`` (a package trained before checkpoints recorded motions): the training
    split's motions of the config, lead and clip, as ``dataset make`` cuts them; the held-out ones are not."""
    from segadeform.dataset.make import config_training_motions
    from segadeform.motion import make_motion
    from segadeform.motion.fingerprint import SAME_CAPTURE, capture_distance, joint_speeds, read_motions_record

    rec = read_motions_record(config_training_motions([SAMPLES / "datasets" / "tiny.toml"]))
    assert [n for n, _ in rec] == ["walk-s0"]  # (the entry's name: kind and seed)
    walk = make_motion("walk", seconds=0.5, fps=30.0)
    swing = make_motion("arm_swing", seconds=0.5, fps=30.0, seed=1)
    assert capture_distance(joint_speeds(walk.poses, 30.0), rec[0][1]) < 0.05  # (its ease-in aside)
    assert capture_distance(joint_speeds(swing.poses, 30.0), rec[0][1]) > SAME_CAPTURE


def test_eval_takes_named_samples_and_keeps_every_metric_of_each(synthetic_dataset, tmp_path, body, capsys):
    """A researcher's audit: eval had no way to score a subset (a folder of links did it), and eval.json kept only
    each sample's vertex error, so no subset's table could be made again from it."""
    from segadeform.errors import InputError
    from segadeform.train.evaluate import pick_samples

    res = evaluate(
        synthetic_dataset, body, make_predictors({"lbs": "lbs"}), split="train", samples=["shorts__b0__walk"]
    )
    assert res["samples"] == ["shorts__b0__walk"]
    one = res["by_sample"]["shorts__b0__walk"]
    assert set(one["metrics"]["lbs"]) == set(METRICS) and one["metrics"]["lbs"]["vertex_cm"] == one["vertex_cm"]["lbs"]
    # the split's table is the per-sample numbers' mean: one sample, the same numbers
    assert all(res["models"]["lbs"][k] == pytest.approx(one["metrics"]["lbs"][k]) for k in METRICS)
    full = evaluate(synthetic_dataset, body, make_predictors({"lbs": "lbs"}), split="train")
    assert sorted(full["samples"]) == ["shorts__b0__walk", "skirt__b0__walk"]
    both = full["by_sample"]
    mean = np.mean([both[s]["metrics"]["lbs"]["vertex_cm"] for s in both])
    assert full["models"]["lbs"]["vertex_cm"] == pytest.approx(mean)
    # a sample of another split, a name twice, none: each said
    with pytest.raises(InputError, match=r"not a sample of the 'train' split.*got skirt__b0__swing"):
        pick_samples(full["samples"], ["skirt__b0__swing"], "train", synthetic_dataset)
    with pytest.raises(InputError, match="named twice"):
        pick_samples(full["samples"], ["skirt__b0__walk"] * 2, "train", synthetic_dataset)
    # the command line: --sample, and a wrong one is one line, exit 1, no report
    out = tmp_path / "ev"
    args = ["eval", str(synthetic_dataset), "-m", "lbs=lbs", "--split", "train", "--sample", "skirt__b0__walk"]
    assert main([*args, "-o", str(out)]) == 0
    assert json.loads((out / "eval.json").read_text())["samples"] == ["skirt__b0__walk"]
    capsys.readouterr()
    bad = tmp_path / "bad"
    assert main([*args[:-1], "nope__b0__walk", "-o", str(bad)]) == 1
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "nope__b0__walk" in err[0] and "'train' split" in err[0], err
    assert not bad.exists() or not any(bad.iterdir())


def test_eval_and_train_without_torch_say_so_in_one_line(synthetic_dataset, tiny_config, tmp_path, monkeypatch, capsys):
    """A new user's walkthrough: `eval` after the Quick start's install (no torch extra) ended in a
    ModuleNotFoundError traceback; both commands now say what to install, exit 1, writing nothing."""
    import importlib.util

    real = importlib.util.find_spec
    monkeypatch.setattr(
        importlib.util, "find_spec", lambda name, *a, **k: None if name == "torch" else real(name, *a, **k)
    )
    out = tmp_path / "ev"
    assert main(["eval", str(synthetic_dataset), "-m", "lbs=lbs", "-o", str(out)]) == 1
    err = capsys.readouterr().err.strip().splitlines()
    assert err == ["Error: eval needs the 'torch' extra: pip install 'segadeform[torch]'"], err
    assert main(["train", str(tiny_config), "-o", str(tmp_path / "run"), "--dataset", str(synthetic_dataset)]) == 1
    assert "train needs the 'torch' extra" in capsys.readouterr().err
    assert not out.exists() and not (tmp_path / "run").exists()
